"""The visual hull of masked captures (data/normalize.py): the box that holds the object, points inside it,
and uniform samples of it (the splat method's initial Gaussians), on exact silhouettes of a sphere."""

from __future__ import annotations

import numpy as np

from nerfkit.data.normalize import inside_visual_hull, masked_bound, sample_visual_hull
from nerfkit.data.procedural.scene import look_at
from nerfkit.rays.cameras import Camera

R, SIZE, FOCAL = 0.5, 48, 60.0


def sphere_views(n_azimuth: int = 8, elevations=(-40, 0, 40)):
    """(poses [N, 4, 4], cameras, alphas uint8 [N, H, W]) of a sphere of radius R at the origin seen from 3 units."""
    poses, alphas = [], []
    j, i = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    d_cam = np.stack([(j - SIZE / 2) / FOCAL, -(i - SIZE / 2) / FOCAL, -np.ones_like(j)], -1)
    for el in np.radians(elevations):
        for az in np.linspace(0, 2 * np.pi, n_azimuth, endpoint=False):
            c2w = look_at(3.0 * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]))
            d = d_cam @ c2w[:3, :3].T
            o = c2w[:3, 3]
            b, c = 2 * d @ o, o @ o - R * R
            hit = b * b - 4 * np.sum(d * d, -1) * c > 0
            poses.append(c2w)
            alphas.append((hit * 255).astype(np.uint8))
    return np.stack(poses), [Camera.pinhole(SIZE, SIZE, FOCAL)] * len(poses), np.stack(alphas)


def test_the_hull_holds_the_sphere_and_little_else():
    poses, cams, alphas = sphere_views()
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    # a pixel of the silhouettes spans 3 / FOCAL = 0.05 at the sphere: points a pixel inside are in, two out are out
    assert inside_visual_hull(dirs * (R - 0.05), poses, cams, alphas).all()
    assert inside_visual_hull(dirs * (R + 0.1), poses, cams, alphas).mean() < 0.05
    b = masked_bound(poses, cams, alphas)
    assert R <= b <= 1.1 * (R + 0.1)


def test_samples_are_uniform_in_the_hull():
    poses, cams, alphas = sphere_views()
    pts = sample_visual_hull(3000, 1.5, poses, cams, alphas, seed=1)
    assert pts.shape == (3000, 3)
    assert inside_visual_hull(pts, poses, cams, alphas).all()
    r = np.linalg.norm(pts, axis=1)
    assert r.max() < R + 0.1
    # uniform in a ball: P(r < R / 2) = 1/8, and every octant holds an eighth
    assert abs(np.mean(r < R / 2) - 1 / 8) < 0.03
    octant = (pts > 0) @ np.array([1, 2, 4])
    assert np.bincount(octant, minlength=8).min() > 0.8 * 3000 / 8


def test_no_silhouette_no_samples():
    poses, cams, alphas = sphere_views()
    assert sample_visual_hull(100, 1.5, poses, cams, np.zeros_like(alphas)) is None


def test_forward_facing_captures_are_told_from_all_around_ones():
    """view_spread: a few degrees for the forward-facing rig (3-degree turns), about 80 for the ring around the
    objects, 180 for two cameras back to back; forward_facing draws the line at 45."""
    from nerfkit.data.normalize import forward_facing, view_spread
    from nerfkit.data.procedural.captures import forward_poses, ring_poses

    ahead, ring = forward_poses(20, seed=3), ring_poses(20, seed=3)
    assert view_spread(ahead) < 6 and forward_facing(ahead)
    assert view_spread(ring) > 60 and not forward_facing(ring)
    back_to_back = np.stack([ring[0], ring[0] @ np.diag([-1.0, 1.0, -1.0, 1.0])])  # one turned half round
    assert view_spread(back_to_back) == 180.0 and not forward_facing(back_to_back)
    assert not forward_facing(ring[:0])


def test_the_ndc_space_of_a_forward_facing_capture_holds_every_pixel_ray_past_a_near_plane_below_the_points():
    """ndc_space on the forward-facing rig: the near plane lies below all but about 1% of the points (and not far
    below them); every pixel's ray of every photo, from the near plane to 1000 times as deep, lands inside the
    cube (covering), and the cube is not much wider than the rays need (tight: they reach 0.9 of it)."""
    import jax.numpy as jnp

    from nerfkit.data.normalize import mean_camera, ndc_space
    from nerfkit.data.procedural.captures import forward_poses
    from nerfkit.rays.cameras import camera_rays
    from nerfkit.rays.coord import ndc

    poses = forward_poses(12, seed=1)
    cams = [Camera.pinhole(40, 30, 36.0)] * len(poses)
    rng = np.random.default_rng(0)
    frame = mean_camera(poses)
    q = np.stack([rng.uniform(-2, 2, 2000), rng.uniform(-1, 1, 2000), -rng.uniform(2.0, 9.0, 2000)], -1)
    points = q @ frame[:, :3].T + frame[:, 3]
    frame, near, extent = ndc_space(poses, cams, points)
    depth = -(points - frame[:, 3]) @ frame[:, 2]
    assert np.mean(depth < near) <= 0.011 and near >= 0.85 * depth.min(), (near, depth.min())
    most = np.array(-1.0)
    for pose, cam in zip(poses, cams):
        o, d = (a.reshape(-1, 3).astype(np.float64) for a in camera_rays(pose, cam))
        d_depth = -d @ frame[:, 2]
        o_depth = -(o - frame[:, 3]) @ frame[:, 2]
        for scale in (1.0, 1.5, 10.0, 1e3):  # depths along the reference axis
            t = (scale * near - o_depth) / d_depth
            y = np.asarray(ndc(jnp.asarray(o + t[:, None] * d, jnp.float32), frame, near, extent))
            assert np.all(np.abs(y) <= 1 + 1e-4), (scale, np.abs(y).max(0))
            most = np.maximum(most, np.abs(y[:, :2]).max(0))
    assert np.all(most >= 0.9), most
    behind = frame[:, 3] + 3.0 * frame[:, 2]
    with np.testing.assert_raises(ValueError):
        ndc_space(poses, cams, behind[None])
