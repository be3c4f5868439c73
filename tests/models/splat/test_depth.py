"""The median depth of splat renders (models/splat/depth.py): on a flat Gaussian's plane exactly, and against a
brute-force blend of random Gaussians (reference.py's rules) pixel by pixel."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.models.splat.depth import BAND, depth_planes, median_depth
from nerfkit.models.splat.gaussians import render
from nerfkit.models.splat.project import project_gaussians
from nerfkit.models.splat.reference import T_MIN, gaussian_alpha, pixel_centres
from nerfkit.rays.cameras import Camera

SIZE, FOCAL = 48, 50.0


def camera_at(z: float) -> np.ndarray:
    """An OpenGL camera on the z axis looking down -z."""
    c2w = np.eye(4, dtype=np.float32)
    c2w[2, 3] = z
    return c2w


def gaussians(means, log_scales, quats, opacity) -> dict:
    n = len(means)
    return {"means": np.asarray(means, np.float32), "log_scales": np.asarray(log_scales, np.float32),
            "quats": np.asarray(quats, np.float32), "opacity": np.asarray(opacity, np.float32),
            "sh_dc": np.zeros((n, 1, 3), np.float32), "sh_rest": np.zeros((n, 15, 3), np.float32)}


def pixel_rays(c2w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origin [3], directions [H, W, 3] with z-depth 1 along them), world frame."""
    u, v = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    d = np.stack([(u - SIZE / 2) / FOCAL, -(v - SIZE / 2) / FOCAL, -np.ones_like(u)], -1) @ c2w[:3, :3].T
    return c2w[:3, 3], d


def test_a_flat_gaussian_gives_the_depth_of_its_plane_where_the_expected_depth_is_its_centres():
    n = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    axis = np.cross([0, 0, 1.0], n)
    half = 0.5 * np.arctan2(np.linalg.norm(axis), n[2])
    q = np.r_[np.cos(half), np.sin(half) * axis / np.linalg.norm(axis)]
    p = gaussians([[0.1, -0.1, 0.0]], np.log([[0.8, 0.8, 1e-4]]), [q], [5.0])
    c2w, cam = camera_at(4.0), Camera.pinhole(SIZE, SIZE, FOCAL)
    alpha = render(p, c2w, cam, backend="numba")["alpha"]
    med = median_depth(p, c2w, (FOCAL, FOCAL, SIZE / 2, SIZE / 2), SIZE, SIZE, alpha)
    o, d = pixel_rays(c2w)
    exact = ((p["means"][0] - o) @ n) / (d @ n)  # z-depth where each pixel's ray meets the plane
    shown = alpha > 0.5
    assert shown.sum() > 300
    np.testing.assert_allclose(med[shown], exact[shown], atol=1e-5)
    expected = render(p, c2w, cam, backend="numba")["depth"] / np.maximum(alpha, 1e-6)
    assert np.abs(expected - exact)[shown].max() > 0.1  # what the plane depth corrects: the centre's depth
    assert (med[alpha == 0] == 0).all()


@pytest.mark.parametrize("band", [0.0, BAND])
def test_median_depth_matches_a_brute_force_blend_of_random_gaussians(band):
    rng = np.random.default_rng(0)
    n = 60
    p = gaussians(rng.uniform(-0.8, 0.8, (n, 3)), rng.uniform(np.log(0.05), np.log(0.4), (n, 3)),
                  rng.normal(size=(n, 4)), rng.uniform(-1, 3, n))
    c2w, intr = camera_at(3.0), (FOCAL, FOCAL, SIZE / 2, SIZE / 2)
    proj = project_gaussians(*(jnp.asarray(p[k]) for k in ("means", "log_scales", "quats")), jnp.asarray(c2w), intr,
                             SIZE, SIZE)
    opac = 1 / (1 + np.exp(-p["opacity"].astype(np.float64)))
    alpha = np.asarray(gaussian_alpha(pixel_centres(SIZE, SIZE),
                                      proj["means2d"], proj["conics"], jnp.asarray(opac, jnp.float32)), np.float64)
    alpha[:, np.asarray(proj["radii"]) == 0] = 0.0
    order = np.argsort(np.asarray(proj["depths"]), kind="stable")
    planes = depth_planes(p, c2w, intr)
    o, d = pixel_rays(c2w)
    want = np.zeros(SIZE * SIZE)
    t_final = np.ones(SIZE * SIZE)
    spread = []  # pixels whose band spans more than one Gaussian: where the band mean is not the median
    for pix in range(SIZE * SIZE):
        t, steps = 1.0, []
        for g in order:
            a = alpha[pix, g]
            if a == 0:
                continue
            if t * (1 - a) < T_MIN:
                break
            steps.append((g, 1 - t, 1 - t * (1 - a)))  # the running opacity before and after g
            t *= 1 - a
        t_final[pix] = t
        lo, hi = (0.5 - band) * (1 - t), (0.5 + band) * (1 - t)
        r = (c2w[:3, :3].T @ d.reshape(-1, 3)[pix]) * [1, -1, -1]  # OpenCV camera axes: (x, y, 1)
        num = den = 0.0
        used = 0
        for g, before, after in steps:
            if after < lo:
                continue
            pm = np.array([[planes[g, 0], planes[g, 1], planes[g, 2]], [planes[g, 1], planes[g, 3], planes[g, 4]],
                           [planes[g, 2], planes[g, 4], planes[g, 5]]])
            tz = np.clip(r @ planes[g, 6:9] / (r @ pm @ r), planes[g, 13], planes[g, 14])
            w = min(after, hi) - max(before, lo)
            if w > 0:
                num, den, used = num + w * tz, den + w, used + 1
            if after >= hi:
                want[pix] = num / den if den > 0 else tz
                break
        spread.append(used > 1)
    got = median_depth(p, c2w, intr, SIZE, SIZE, (1 - t_final).reshape(SIZE, SIZE), band=band)
    covered = t_final < 0.5
    assert covered.sum() > 200  # the comparison sees many opaque pixels
    if band > 0:
        assert np.mean(spread) > 0.2  # and many pixels where the band mean differs from the median
        assert np.abs(got.ravel() - median_depth(p, c2w, intr, SIZE, SIZE, (1 - t_final).reshape(SIZE, SIZE),
                                                 band=0.0).ravel()).max() > 0.05
    np.testing.assert_allclose(got.ravel(), want, atol=2e-4)


def test_float64_rotations_are_the_projections_rotations():
    from nerfkit.models.splat.depth import rotations
    from nerfkit.models.splat.project import quaternion_to_rotation

    q = np.random.default_rng(0).normal(size=(50, 4)).astype(np.float32)
    r = rotations(q)
    np.testing.assert_allclose(r, np.asarray(quaternion_to_rotation(jnp.asarray(q))), atol=1e-6)
    np.testing.assert_allclose(r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
