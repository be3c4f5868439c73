"""Reading SfM points (data/points.py) and moving them by a similarity."""

import numpy as np
import pytest
import trimesh

from nerfkit.data.points import read_points, transform_points


def test_read_points_ply_with_transform(tmp_path):
    pts = np.random.default_rng(1).normal(size=(30, 3))
    rgba = np.concatenate([np.random.default_rng(2).integers(0, 256, (30, 3)), np.full((30, 1), 255)], 1)
    trimesh.PointCloud(pts, colors=rgba.astype(np.uint8)).export(tmp_path / "sparse_pc.ply")
    m = np.diag([2.0, 2.0, 2.0, 1.0])
    m[:3, 3] = [1, 2, 3]
    xyz, col = read_points(tmp_path / "sparse_pc.ply", transform=m)
    np.testing.assert_allclose(xyz, 2 * pts + [1, 2, 3], atol=2e-6)  # float32 in the file
    np.testing.assert_allclose(col, rgba[:, :3] / 255.0, atol=1e-6)
    np.testing.assert_allclose(transform_points(pts, m), 2 * pts + [1, 2, 3])


def test_far_sphere_points_take_the_colour_of_the_first_photo_that_sees_them():
    """Each photo a flat colour of its own: a far point's colour names the photo it was coloured by, which must be
    the first (in order) that it projects into; points on the sphere only, points no photo sees dropped."""
    from nerfkit.data.points import far_sphere_points
    from nerfkit.data.procedural.captures import ring_poses
    from nerfkit.rays.cameras import Camera, project_points

    poses = ring_poses(6, seed=1)
    cam = Camera.pinhole(32, 24, 20.0)
    images = np.stack([np.full((24, 32, 3), k / 10, np.float32) for k in range(6)])
    pts, colours = far_sphere_points(4000, 12.0, poses, [cam] * 6, images, seed=2)
    assert 100 < len(pts) < 4000  # the cameras see part of the sphere only
    assert np.allclose(np.linalg.norm(pts, axis=1), 12.0)
    which = np.round(colours[:, 0] * 10).astype(int)
    for k, c2w in enumerate(poses):
        u, v, front = project_points(pts, c2w, cam)
        inside = front & (u >= 0) & (u < 32) & (v >= 0) & (v < 24)
        assert np.all(inside[which == k])
        assert not np.any(inside & (which > k)), k  # no point an earlier photo sees took a later one's colour


def test_far_points_through_photos_lie_where_their_pixels_look():
    """A forward-facing rig: every point is on the sphere, projects back onto the pixel it was drawn at (the
    photos' colours vary across the image, so the colour names the pixel) in the photo it came from, and the
    photos share the points about evenly; the uniform sphere keeps about a tenth of its points here."""
    from nerfkit.data.points import far_points_through_photos, far_sphere_points
    from nerfkit.data.procedural.captures import forward_poses
    from nerfkit.rays.cameras import Camera, project_points

    poses = forward_poses(6, seed=1)
    cam = Camera.pinhole(32, 24, 30.0)
    ramp = np.stack(np.meshgrid(np.arange(32) / 32, np.arange(24) / 24), -1)  # [24, 32, 2]: (u, v) / size
    images = np.stack([np.concatenate([ramp, np.full((24, 32, 1), k / 10)], -1) for k in range(6)]).astype(np.float32)
    pts, colours = far_points_through_photos(3000, 12.0, poses, [cam] * 6, images, seed=2)
    assert pts.shape == (3000, 3) and np.allclose(np.linalg.norm(pts, axis=1), 12.0)
    which = np.round(colours[:, 2] * 10).astype(int)
    assert np.bincount(which, minlength=6).min() > 3000 / 6 * 0.8
    for k, c2w in enumerate(poses):
        u, v, front = project_points(pts[which == k], c2w, cam)
        assert np.all(front)
        np.testing.assert_allclose(np.floor(u) / 32, colours[which == k, 0], atol=1e-6)
        np.testing.assert_allclose(np.floor(v) / 24, colours[which == k, 1], atol=1e-6)
    kept, _ = far_sphere_points(3000, 12.0, poses, [cam] * 6, images, seed=2)
    assert len(kept) < 0.2 * 3000  # measured 359


def test_far_radius_lies_beyond_the_cameras_and_beyond_most_of_what_sfm_saw():
    """3 x the farthest camera's distance while the points lie inside it; the 95th percentile of the points'
    distances where a far wall lies beyond it (not the few outliers past the wall, not the near objects)."""
    from nerfkit.data.points import far_radius

    poses = np.tile(np.eye(4), (5, 1, 1))
    poses[:, :3, 3] = [[4, 0, 0], [0, 4, 0], [0, 0, 4], [-4, 0, 0], [0, -2, 0]]
    rng = np.random.default_rng(0)
    unit = rng.normal(size=(1000, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    near = unit[:600] * rng.uniform(0, 2, (600, 1))  # objects inside the ring of cameras
    assert far_radius(poses, None, 3.0, 0.95) == far_radius(poses, near, 3.0, 0.95) == 12.0
    assert far_radius(poses, np.zeros((0, 3)), 3.0, 0.95) == 12.0
    wall = unit[600:980] * 40.0  # a far wall beyond the sphere of 12
    outliers = unit[980:] * 500.0  # 2% badly triangulated
    r = far_radius(poses, np.concatenate([near, wall, outliers]), 3.0, 0.95)
    assert r == pytest.approx(40.0)
    assert far_radius(poses, np.concatenate([near, wall, outliers]), 3.0, 0.5) == 12.0  # the median is near
