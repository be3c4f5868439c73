"""Gaussian parameters: initialisation from points / at random, point-cloud reading, render() outputs."""

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.models.splat.gaussians import (
    INIT_OPACITY,
    N_REST,
    init_from_points,
    init_random,
    knn_log_scales,
    render,
    render_frame,
)
from nerfkit.models.splat.project import sh_colors
from nerfkit.rays.cameras import Camera, look_at

CAM = Camera.pinhole(40, 32, 45.0)
C2W = look_at(np.array([0.0, -4.0, 0.0]), np.zeros(3))


def test_init_from_points_grid():
    # a grid of spacing h: every inner point has 6 neighbours at distance h, so the 3-NN mean is h
    h = 0.1
    g = np.stack(np.meshgrid(*[np.arange(5) * h] * 3, indexing="ij"), -1).reshape(-1, 3)
    colors = np.random.default_rng(0).uniform(size=(len(g), 3)).astype(np.float32)
    p = init_from_points(g, colors)
    assert {k: v.shape for k, v in p.items()} == {
        "means": (125, 3), "log_scales": (125, 3), "quats": (125, 4), "opacity": (125,), "sh_dc": (125, 1, 3),
        "sh_rest": (125, N_REST, 3)}
    np.testing.assert_allclose(np.exp(p["log_scales"]), h, rtol=1e-5)
    np.testing.assert_array_equal(p["quats"], np.tile([1, 0, 0, 0], (125, 1)))
    np.testing.assert_allclose(1 / (1 + np.exp(-p["opacity"])), INIT_OPACITY, rtol=1e-6)
    sh = jnp.concatenate([jnp.asarray(p["sh_dc"]), jnp.asarray(p["sh_rest"])], 1)
    col = sh_colors(sh, jnp.asarray(p["means"]), jnp.array([0.0, 0.0, 5.0]), 3)  # bands >= 1 are zero
    np.testing.assert_allclose(col, colors, atol=1e-6)
    # uint8 colours are divided by 255; a duplicated point gets the floor, not log(0)
    q = init_from_points(np.zeros((4, 3)), np.full((4, 3), 255, np.uint8))
    assert np.all(np.isfinite(q["log_scales"]))
    assert knn_log_scales(np.zeros((1, 3))).shape == (1, 3)


def test_init_random_in_box():
    p = init_random(500, box=1.5, seed=3)
    assert p["means"].shape == (500, 3) and np.abs(p["means"]).max() <= 1.5
    assert np.all(np.isfinite(p["log_scales"])) and p["means"].dtype == np.float32


def test_render_outputs_and_depth():
    # one opaque-ish Gaussian at the origin, 4 units in front of the camera
    p = init_from_points(np.zeros((1, 3)), np.array([[0.2, 0.4, 0.6]]), opacity=0.9)
    p["log_scales"][:] = np.log(0.3)
    out = render(p, C2W, CAM, background=(1.0, 1.0, 1.0))
    assert out["rgb"].shape == (32, 40, 3) and out["depth"].shape == (32, 40) and out["alpha"].shape == (32, 40)
    a = out["alpha"][16, 20]
    assert 0.85 < a <= 0.9  # the centre pixel is 0.5 px off the mean
    np.testing.assert_allclose(out["rgb"][16, 20], a * np.array([0.2, 0.4, 0.6]) + (1 - a), atol=1e-5)
    np.testing.assert_allclose(out["depth"], 4.0 * out["alpha"], atol=1e-5)  # sum_k w_k z_k, z = 4
    assert out["alpha"][0, 0] == 0.0 and np.allclose(out["rgb"][0, 0], 1.0)
    assert "depth" not in render(p, C2W, CAM, depth=False)


@pytest.mark.parametrize("backend", ["numba", "reference"])
def test_render_frame_is_render_clipped(backend, monkeypatch):
    """render_frame (the renderer's path: a view only looked at) gives render()'s outputs with rgb clipped to
    [0, 1], through the backend's host `frame` where it has one (numba: called, counted here) and render()
    where it has none (reference)."""
    from nerfkit.models.splat import backends, gaussians

    p = init_random(60, box=1.0, seed=4, opacity=0.8)
    p["sh_dc"] = (np.random.default_rng(4).normal(size=p["sh_dc"].shape) * 6.0).astype(np.float32)  # colours past 1
    calls = []
    b = backends.backend(backend)
    if b.frame is not None:
        counted = backends.Backend(b.name, b.summary, b.rasterize, b.contrib,
                                   lambda *a: calls.append(1) or b.frame(*a))
        monkeypatch.setattr(gaussians, "backend_named", lambda name: counted)
    want = render(p, C2W, CAM, background=(0.2, 0.5, 1.0), backend=backend)
    got = render_frame(p, C2W, CAM, background=(0.2, 0.5, 1.0), backend=backend)
    assert len(calls) == (b.frame is not None)
    assert (want["rgb"] > 1).any()  # the clip is exercised (SH colours are clamped at 0, so none is below)
    np.testing.assert_allclose(got["rgb"], np.clip(want["rgb"], 0, 1), atol=1e-6)
    for k in ("depth", "alpha"):
        np.testing.assert_allclose(got[k], want[k], atol=1e-5)
    assert "depth" not in render_frame(p, C2W, CAM, depth=False, backend=backend)


def test_distorted_camera_refused():
    cam = Camera(40, 32, 45.0, 45.0, 20.0, 16.0, "OPENCV", (45.0, 45.0, 20.0, 16.0, 0.1, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="pinhole"):
        render(init_random(3), C2W, cam)
