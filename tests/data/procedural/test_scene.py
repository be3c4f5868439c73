"""Tests for the procedural demo scene (nerfkit.data.procedural.scene)."""

import json
import math

import imageio.v3 as iio
import numpy as np
import pytest

from nerfkit.core.errors import DataError
from nerfkit.data.procedural import scene


def test_ray_at_sphere_centre_hits_at_distance_minus_radius():
    # From straight above the big sphere (nothing else lies on this vertical line),
    # with a non-unit direction: t is measured in units of |d|.
    c, r = scene.BIG_SPHERE_CENTER, scene.BIG_SPHERE_RADIUS
    o = c + np.array([0.0, 0.0, 3.0])
    d = np.array([0.0, 0.0, -2.0])
    rgb, alpha, t = scene.trace(o, d)
    assert alpha == 1.0
    np.testing.assert_allclose(t, (3.0 - r) / 2.0, rtol=1e-6)
    assert rgb.shape == (3,) and np.all(rgb > 0) and np.all(rgb <= 1)


def test_small_sphere_hit_along_diagonal():
    c, r = scene.SMALL_SPHERE_CENTER, scene.SMALL_SPHERE_RADIUS
    d = np.array([-0.3, 1.0, -0.2])  # from the -y side: no other solid in the way
    o = c - 2.5 * d
    _, alpha, t = scene.trace(o[None], d[None])
    dist = np.linalg.norm(c - o)
    np.testing.assert_allclose(t[0], (dist - r) / np.linalg.norm(d), rtol=1e-6)
    assert alpha[0] == 1.0


def test_miss_gives_zero_alpha_inf_t_black_rgb():
    o = np.array([[5.0, 5.0, 5.0], [0.0, 0.0, 4.0]])
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # away from / past the scene
    rgb, alpha, t = scene.trace(o, d)
    np.testing.assert_array_equal(alpha, 0.0)
    assert np.all(np.isinf(t)) and np.all(t > 0)
    np.testing.assert_array_equal(rgb, 0.0)
    assert rgb.dtype == alpha.dtype == t.dtype == np.float32


def test_trace_keeps_batch_shape_and_takes_nearest_hit():
    # A ray from below the ground, going up through the ground slab into the box:
    # the slab bottom is hit first.
    x, y = 0.45, 0.35  # under the box
    o = np.broadcast_to(np.array([x, y, -3.0]), (2, 3, 3))
    d = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (2, 3, 3))
    rgb, alpha, t = scene.trace(o, d)
    assert rgb.shape == (2, 3, 3) and alpha.shape == t.shape == (2, 3)
    np.testing.assert_allclose(t, scene.GROUND_Z_RANGE[0] - (-3.0), rtol=1e-6)
    # From above, the box top (z = BOX_MAX.z) comes first.
    _, _, t_top = scene.trace(np.array([x, y, 3.0]), np.array([0.0, 0.0, -1.0]))
    np.testing.assert_allclose(t_top, 3.0 - scene.BOX_MAX[2], rtol=1e-6)


def test_camera_rays_centre_and_corner_pinhole():
    h, w, focal = 6, 8, 10.0
    c2w = np.eye(4)
    c2w[:3, 3] = (0.0, 0.0, 4.0)  # at (0, 0, 4), looking down -z at the origin
    o, d = scene.camera_rays(c2w, h, w, focal)
    assert o.shape == d.shape == (h, w, 3)
    np.testing.assert_array_equal(o, np.broadcast_to([0.0, 0.0, 4.0], (h, w, 3)))
    # Even size: the four central pixels straddle the axis; their mean is exactly -z,
    # and each is within half a pixel diagonal of it.
    centre = d[h // 2 - 1 : h // 2 + 1, w // 2 - 1 : w // 2 + 1].reshape(-1, 3)
    np.testing.assert_allclose(centre.mean(0), [0.0, 0.0, -1.0], atol=1e-12)
    assert np.all(np.abs(centre[:, :2]) <= 0.5 / focal + 1e-12)
    # Top-left pixel points left (-x) and up (+y); bottom-right right and down.
    np.testing.assert_allclose(d[0, 0], [(0.5 - w / 2) / focal, -(0.5 - h / 2) / focal, -1.0])
    np.testing.assert_allclose(
        d[h - 1, w - 1], [(w - 0.5 - w / 2) / focal, -(h - 0.5 - h / 2) / focal, -1.0]
    )


def test_camera_rays_rotated_camera_and_z_depth():
    # A look-at camera: directions are R d_cam, so the centre-pixel mean is the camera's
    # -z axis and the depth of the origin-bound ray is the distance to the origin.
    c2w = scene.orbit_pose(0.7, math.radians(30.0))
    np.testing.assert_allclose(np.linalg.norm(c2w[:3, 3]), scene.CAMERA_RADIUS)
    np.testing.assert_allclose(c2w[:3, :3] @ c2w[:3, :3].T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(-c2w[:3, 2], -c2w[:3, 3] / scene.CAMERA_RADIUS, atol=1e-12)
    o, d = scene.camera_rays(c2w, 4, 4, 5.0)
    np.testing.assert_allclose(d[1:3, 1:3].reshape(-1, 3).mean(0), -c2w[:3, 2], atol=1e-12)
    # Each direction has unit component along the viewing axis: t is z-depth.
    np.testing.assert_allclose(d @ -c2w[:3, 2], 1.0, atol=1e-12)


def test_look_at_points_camera_at_target_with_up_z():
    c2w = scene.look_at([0.0, -4.0, 1.0])
    z = c2w[:3, 2]
    np.testing.assert_allclose(z, np.array([0.0, -4.0, 1.0]) / math.sqrt(17.0))
    assert c2w[2, 1] > 0  # camera +y has a positive world-z component
    np.testing.assert_allclose(np.linalg.det(c2w[:3, :3]), 1.0)


def test_make_scene_files_and_depth_round_trip(tmp_path):
    size = 32
    counts = {"train": 4, "val": 2, "test": 2}
    out = scene.make_scene(tmp_path, size=size, n_train=4, n_val=2, n_test=2)
    assert out == tmp_path
    bound = math.sqrt(3.0) * scene.SCENE_BOUNDS
    poses = {}
    for split, n in counts.items():
        meta = json.loads((tmp_path / f"transforms_{split}.json").read_text())
        assert meta["camera_angle_x"] == pytest.approx(0.6911112070083618)
        focal = 0.5 * size / math.tan(0.5 * meta["camera_angle_x"])
        assert len(meta["frames"]) == n
        for k, frame in enumerate(meta["frames"]):
            assert frame["file_path"] == f"./{split}/r_{k}"
            assert frame["rotation"] == 0.0
            c2w = np.array(frame["transform_matrix"])
            assert c2w.shape == (4, 4)
            np.testing.assert_allclose(c2w[3], [0, 0, 0, 1])
            np.testing.assert_allclose(np.linalg.norm(c2w[:3, 3]), scene.CAMERA_RADIUS)
            poses.setdefault(split, []).append(c2w)

            img = iio.imread(tmp_path / f"{frame['file_path']}.png")
            assert img.shape == (size, size, 4) and img.dtype == np.uint8
            alpha = img[..., 3]
            assert set(np.unique(alpha)) == {0, 255}  # binary, both fg and bg present
            np.testing.assert_array_equal(img[..., :3][alpha == 0], 0)

            depth = np.load(tmp_path / split / f"r_{k}_depth.npy")
            assert depth.shape == (size, size) and depth.dtype == np.float32
            np.testing.assert_array_equal(np.isfinite(depth), alpha > 0)
            assert np.all(np.isposinf(depth[alpha == 0]))
            fg = depth[alpha > 0]
            assert fg.min() >= scene.CAMERA_RADIUS - bound
            assert fg.max() <= scene.CAMERA_RADIUS + bound

            # Re-trace from the JSON pose: the pose convention round-trips exactly.
            rgb, a, t = scene.trace(*scene.camera_rays(c2w, size, size, focal))
            np.testing.assert_array_equal(a * 255, alpha)
            np.testing.assert_allclose(t, depth, rtol=1e-6)
            np.testing.assert_array_equal(np.round(rgb * a[..., None] * 255), img[..., :3])

    # Elevations: train/val in [10, 70] deg, test exactly 30 deg; splits differ.
    for split in ("train", "val"):
        for c2w in poses[split]:
            el = math.degrees(math.asin(c2w[2, 3] / scene.CAMERA_RADIUS))
            assert 10.0 - 1e-9 <= el <= 70.0 + 1e-9
    for c2w in poses["test"]:
        np.testing.assert_allclose(c2w[2, 3], scene.CAMERA_RADIUS * 0.5, atol=1e-12)
    assert not np.allclose(poses["train"][0], poses["val"][0])


def test_make_scene_is_deterministic_in_seed(tmp_path):
    a = scene.make_scene(tmp_path / "a", size=8, n_train=2, n_val=1, n_test=1, seed=3)
    b = scene.make_scene(tmp_path / "b", size=8, n_train=2, n_val=1, n_test=1, seed=3)
    c = scene.make_scene(tmp_path / "c", size=8, n_train=2, n_val=1, n_test=1, seed=4)
    ja = (a / "transforms_train.json").read_text()
    assert ja == (b / "transforms_train.json").read_text()
    assert ja != (c / "transforms_train.json").read_text()


def test_geometry_constants_inside_bounds():
    b = scene.SCENE_BOUNDS
    for c, r in (
        (scene.BIG_SPHERE_CENTER, scene.BIG_SPHERE_RADIUS),
        (scene.SMALL_SPHERE_CENTER, scene.SMALL_SPHERE_RADIUS),
    ):
        assert np.all(np.abs(c) + r <= b)
    assert np.all(np.abs(scene.BOX_MIN) <= b) and np.all(np.abs(scene.BOX_MAX) <= b)
    assert np.all(np.abs(scene.CYLINDER_CENTER_XY) + scene.CYLINDER_RADIUS <= b)
    assert max(map(abs, scene.CYLINDER_Z_RANGE + scene.GROUND_Z_RANGE)) <= b
    assert scene.GROUND_RADIUS <= b


def test_make_scene_rejects_bad_size(tmp_path):
    with pytest.raises(DataError, match="size"):
        scene.make_scene(tmp_path, size=0)


def test_render_view_supersample_integrates_the_pixel_area():
    """Each supersampled pixel is the mean of S x S point samples: its alpha is the mean of the fine render's, its
    colour the mean of the premultiplied colour over that alpha. So the edges get fractional alpha, the interior
    keeps the point-sampled colour, and the depth stays the pixel centre's."""
    c2w = scene.look_at((0.0, -scene.CAMERA_RADIUS, 1.0))
    point, depth = scene.render_view(c2w, 16)
    area, depth_area = scene.render_view(c2w, 16, supersample=3)
    fine, _ = scene.render_view(c2w, 48)
    np.testing.assert_array_equal(depth_area, depth)
    want_alpha = fine[..., 3].astype(np.float64).reshape(16, 3, 16, 3).mean((1, 3))
    np.testing.assert_allclose(area[..., 3], want_alpha, atol=1.01)
    edge = (area[..., 3] > 0) & (area[..., 3] < 255)
    assert edge.sum() >= 16  # the objects' outlines, not a point-sampled 0/1 mask
    assert set(np.unique(point[..., 3])) <= {0, 255}
    inner = (area[..., 3] == 255)
    premult = (fine[..., :3].astype(np.float64) * fine[..., 3:] / 255.0).reshape(16, 3, 16, 3, 3).mean((1, 3))
    np.testing.assert_allclose(area[inner][:, :3], premult[inner], atol=1.01)  # two roundings to uint8
