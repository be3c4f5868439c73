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
