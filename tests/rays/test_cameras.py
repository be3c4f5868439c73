"""Tests for pinhole cameras and rays (nerfkit.rays.cameras).

Reference answers come from an independent pinhole model written here with an OpenCV
style intrinsic matrix K (pixel centres at integer + 0.5) and the OpenGL -> OpenCV axis
flip diag(1, -1, -1), not from the formula in cameras.py.

Poses from `look_at` are float32, so positions of magnitude ~4 carry ~4 * 2^-24 ~ 2.4e-7
rounding per coordinate, and a handful of float32 products add a few times that: an
absolute tolerance of 1e-5 (about 40 ulp at magnitude 4) is used for world-space points.
"""

import math

import numpy as np
import pytest
import reference

from nerfkit.data.procedural.scene import make_scene
from nerfkit.rays import cameras

FLIP = np.diag([1.0, -1.0, -1.0])  # OpenGL camera axes (x right, y up, -z forward) -> OpenCV


def intrinsics(height, width, focal):
    return np.array([[focal, 0.0, 0.5 * width], [0.0, focal, 0.5 * height], [0.0, 0.0, 1.0]])


def project(c2w, x_world, height, width, focal):
    """(u, v, z_depth) of world points [..., 3]: u = column coordinate, v = row coordinate.

    Pixel (i, j) has its centre at (u, v) = (j + 0.5, i + 0.5).
    """
    w2c = np.linalg.inv(np.asarray(c2w, np.float64))  # exact inverse (float32 R is not exactly orthonormal)
    x_cam = np.asarray(x_world, np.float64) @ w2c[:3, :3].T + w2c[:3, 3]
    x_cv = x_cam @ FLIP.T
    uvw = x_cv @ intrinsics(height, width, focal).T
    return uvw[..., 0] / uvw[..., 2], uvw[..., 1] / uvw[..., 2], x_cv[..., 2]


def unproject(c2w, i, j, depth, height, width, focal):
    """World point at z-depth `depth` on the pixel centre (i, j), via K^-1 (independent path)."""
    c2w = np.asarray(c2w, np.float64)
    uv1 = np.array([j + 0.5, i + 0.5, 1.0])
    x_cv = depth * (np.linalg.inv(intrinsics(height, width, focal)) @ uv1)
    return c2w[:3, :3] @ (FLIP @ x_cv) + c2w[:3, 3]


def rotated_camera():
    return cameras.look_at(np.array([2.5, -3.0, 1.5]), np.array([0.2, 0.1, -0.3]))


# --- pixel <-> point ----------------------------------------------------------------------


def test_ray_through_pixel_hits_point_projecting_there_axis_aligned_camera():
    # Camera at (0, 0, 4) looking at the origin: look_at falls back to the identity rotation.
    c2w = cameras.look_at(np.array([0.0, 0.0, 4.0]), np.zeros(3))
    np.testing.assert_array_equal(c2w[:3, :3], np.eye(3, dtype=np.float32))
    h, w, f = 7, 9, 20.0
    # x = (0.3, -0.3, 1): camera coords (0.3, -0.3, -3), z-depth 3, so
    # u = W/2 + f * 0.3/3 = 6.5 and v = H/2 + f * 0.3/3 = 5.5: the centre of pixel (5, 6).
    x = np.array([0.3, -0.3, 1.0])
    u, v, z = project(c2w, x, h, w, f)
    assert (u, v, z) == pytest.approx((6.5, 5.5, 3.0), abs=1e-12)
    i, j = int(v - 0.5), int(u - 0.5)  # pixel (5, 6)
    o, d = reference.rays_from_pixels(c2w, np.float32(i), np.float32(j), h, w, f)
    np.testing.assert_allclose(o + z * d, x, atol=1e-5)
    # The same ray out of the full-image ray bundle.
    O, D = reference.image_rays(c2w, h, w, f)
    np.testing.assert_allclose(O[i, j] + z * D[i, j], x, atol=1e-5)


@pytest.mark.parametrize("ij", [(0, 0), (3, 4), (6, 8), (1, 7)])
def test_ray_through_pixel_hits_point_projecting_there_rotated_camera(ij):
    c2w = rotated_camera()
    h, w, f = 7, 9, 11.0
    i, j = ij
    depth = 3.7
    x = unproject(c2w, i, j, depth, h, w, f)
    # The point really projects onto that pixel centre (checks the reference model itself).
    u, v, z = project(c2w, x, h, w, f)
    np.testing.assert_allclose([u, v, z], [j + 0.5, i + 0.5, depth], atol=1e-9)
    O, D = reference.image_rays(c2w, h, w, f)
    np.testing.assert_allclose(O[i, j] + depth * D[i, j], x, atol=1e-5)
    # A different pixel's ray at the same depth misses the point by about depth / f.
    other = O[i, (j + 1) % w] + depth * D[i, (j + 1) % w]
    assert np.linalg.norm(other - x) > 0.5 * depth / f


def test_rays_through_fractional_pixel_positions_hit_projected_points():
    # Random world points in front of the camera, projected to continuous (u, v): the ray
    # at row v - 0.5, column u - 0.5 (pixel_directions adds the half pixel) passes through them.
    c2w = rotated_camera()
    h, w, f = 40, 60, 50.0
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 0.5, size=(50, 3)) + np.array([0.2, 0.1, -0.3])
    u, v, z = project(c2w, pts, h, w, f)
    assert np.all(z > 0)
    o, d = reference.rays_from_pixels(c2w, (v - 0.5).astype(np.float32), (u - 0.5).astype(np.float32), h, w, f)
    np.testing.assert_allclose(o + z[:, None] * d, pts, atol=1e-5)


def test_principal_point_ray_is_camera_minus_z_for_odd_size():
    c2w = rotated_camera()
    h, w, f = 7, 9, 11.0
    o, d = reference.image_rays(c2w, h, w, f)
    # Odd H, W: pixel (H//2, W//2) has its centre at (W/2, H/2) exactly: d_cam = (0, 0, -1).
    # R (0, 0, -1) involves only exact products with 0 and -1: bit-exact.
    np.testing.assert_array_equal(d[h // 2, w // 2], -c2w[:3, 2])
    np.testing.assert_allclose(o[h // 2, w // 2], c2w[:3, 3], atol=0)
    # The camera looks at its target: -z points from the eye to (0.2, 0.1, -0.3).
    to_target = np.array([0.2, 0.1, -0.3]) - np.array([2.5, -3.0, 1.5])
    np.testing.assert_allclose(-c2w[:3, 2], to_target / np.linalg.norm(to_target), atol=1e-6)


def test_image_rays_shapes_dtype_and_pixel_order():
    c2w = rotated_camera()
    h, w, f = 5, 8, 6.0
    o, d = reference.image_rays(c2w, h, w, f)
    assert o.shape == d.shape == (h, w, 3)
    assert o.dtype == d.dtype == np.float32
    np.testing.assert_array_equal(o, np.broadcast_to(c2w[:3, 3], (h, w, 3)))
    # Camera-space directions: x grows with the column, y decreases with the row.
    d_cam = d @ c2w[:3, :3]  # R^T d for each pixel (R orthonormal)
    np.testing.assert_allclose(d_cam[..., 0], np.broadcast_to((np.arange(w) + 0.5 - w / 2) / f, (h, w)), atol=1e-6)
    np.testing.assert_allclose(d_cam[..., 1], np.broadcast_to(-(np.arange(h)[:, None] + 0.5 - h / 2) / f, (h, w)), atol=1e-6)


def test_directions_have_camera_z_minus_one_so_t_is_z_depth():
    c2w = rotated_camera()
    h, w, f = 6, 10, 7.5
    _, d = reference.image_rays(c2w, h, w, f)
    axis = -c2w[:3, 2].astype(np.float64)  # camera viewing axis (unit)
    np.testing.assert_allclose(d @ axis, 1.0, atol=1e-6)
    # Not normalised: off-axis rays are longer than 1.
    norms = np.linalg.norm(d, axis=-1)
    assert norms.min() > 1.0
    np.testing.assert_allclose(norms[0, 0], math.sqrt(1 + ((0.5 - w / 2) / f) ** 2 + ((0.5 - h / 2) / f) ** 2), rtol=1e-6)


def test_pixel_directions_numpy_and_jax_agree():
    import jax.numpy as jnp

    i = np.array([0.0, 2.0, 4.0], np.float32)
    j = np.array([1.0, 3.0, 5.0], np.float32)
    a = reference.pixel_directions(i, j, 5, 6, 4.0)
    b = reference.pixel_directions(jnp.asarray(i), jnp.asarray(j), 5, 6, 4.0)
    assert isinstance(a, np.ndarray)
    np.testing.assert_allclose(np.asarray(b), a, atol=1e-7)
    np.testing.assert_allclose(a[1], [(3.5 - 3) / 4, -(2.5 - 2.5) / 4, -1.0])


# --- look_at, scene_center, orbit_poses ------------------------------------------------------


def test_look_at_is_rigid_with_world_up():
    for eye in ([3.0, 1.0, 2.0], [0.0, 0.0, 4.0], [0.0, 0.0, -4.0], [-1.0, -2.0, -0.5]):
        c2w = cameras.look_at(np.array(eye), np.zeros(3)).astype(np.float64)
        r = c2w[:3, :3]
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-6)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-6)
        np.testing.assert_array_equal(c2w[3], [0, 0, 0, 1])
        np.testing.assert_allclose(c2w[:3, 3], eye, atol=1e-6)
        # Camera x is horizontal (perpendicular to world up) unless looking straight along it.
        if abs(eye[2]) != np.linalg.norm(eye):
            assert abs(r[2, 0]) < 1e-6
            assert r[2, 1] > 0  # camera up has a positive world-z component


def sphere_cameras(center, radius, elevations, azimuths):
    poses = []
    for el, az in zip(elevations, azimuths):
        eye = center + radius * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        poses.append(cameras.look_at(eye, center))
    return np.stack(poses)


def test_scene_center_recovers_known_target():
    target = np.array([0.4, -0.7, 0.25])
    rng = np.random.default_rng(1)
    n = 7
    poses = sphere_cameras(target, 3.0, rng.uniform(0.1, 1.2, n), rng.uniform(0, 2 * np.pi, n))
    # Also cameras at varied distances: the optical axes still meet at the target.
    eyes = target + rng.normal(size=(4, 3)) * np.array([3.0, 3.0, 1.0]) + np.array([0, 0, 2.0])
    poses = np.concatenate([poses, np.stack([cameras.look_at(e, target) for e in eyes])])
    # float32 axes: angular error ~1e-7 rad at distance <~6 -> ~1e-6 positional error.
    np.testing.assert_allclose(cameras.scene_center(poses), target, atol=1e-5)


def test_scene_center_least_squares_two_skew_axes():
    # Axis 1: the x-axis (through (0,0,0) along x); axis 2: the line z = 1 along y.
    # The closest point to both is the midpoint of their common perpendicular: (0, 0, 0.5).
    p1 = cameras.look_at(np.array([5.0, 0.0, 0.0]), np.zeros(3))
    p2 = cameras.look_at(np.array([0.0, 5.0, 1.0]), np.array([0.0, 0.0, 1.0]))
    poses = np.stack([p1, p2])
    np.testing.assert_allclose(-poses[0, :3, 2], [-1.0, 0.0, 0.0])  # axis along x
    np.testing.assert_allclose(cameras.scene_center(poses), [0.0, 0.0, 0.5], atol=1e-6)


def _radius_elevation(eyes, center):
    rel = eyes - center
    r = np.linalg.norm(rel, axis=-1)
    return r, np.arcsin(rel[:, 2] / r)


def test_orbit_poses_look_at_centre_with_input_radius_and_elevation():
    center = np.array([0.3, -0.2, 0.1])
    radius, elev = 3.5, math.radians(25.0)
    poses = sphere_cameras(center, radius, [elev] * 6, np.linspace(0.3, 5.0, 6))
    n = 8
    orbit = cameras.orbit_poses(poses, n)
    assert orbit.shape == (n, 4, 4)
    eyes = orbit[:, :3, 3].astype(np.float64)
    r, el = _radius_elevation(eyes, center)
    np.testing.assert_allclose(r, radius, atol=1e-5)
    np.testing.assert_allclose(el, elev, atol=1e-5)
    for c2w in orbit.astype(np.float64):
        look = (center - c2w[:3, 3]) / np.linalg.norm(center - c2w[:3, 3])
        np.testing.assert_allclose(-c2w[:3, 2], look, atol=1e-5)
        np.testing.assert_allclose(c2w[:3, :3].T @ c2w[:3, :3], np.eye(3), atol=1e-6)
    # Evenly spaced azimuths starting at 0: consecutive eyes 2 pi / n apart around +z.
    az = np.unwrap(np.arctan2(eyes[:, 1] - center[1], eyes[:, 0] - center[0]))
    np.testing.assert_allclose(az, 2 * np.pi * np.arange(n) / n, atol=1e-5)


def test_orbit_poses_from_generated_scene_use_median_radius_and_elevation(tmp_path):
    make_scene(tmp_path, size=2, n_train=5, n_val=0, n_test=0, seed=7)
    import json

    meta = json.loads((tmp_path / "transforms_train.json").read_text())
    poses = np.array([f["transform_matrix"] for f in meta["frames"]], np.float32)
    _, in_el = _radius_elevation(poses[:, :3, 3].astype(np.float64), np.zeros(3))
    assert np.ptp(in_el) > 0.1  # elevations differ, so the median is meaningful
    orbit = cameras.orbit_poses(poses, 5)
    r, el = _radius_elevation(orbit[:, :3, 3].astype(np.float64), np.zeros(3))
    np.testing.assert_allclose(r, 4.0, atol=1e-5)  # make_scene: CAMERA_RADIUS = 4 around the origin
    np.testing.assert_allclose(el, np.median(in_el), atol=1e-5)
    for c2w in orbit.astype(np.float64):
        np.testing.assert_allclose(-c2w[:3, 2], -c2w[:3, 3] / np.linalg.norm(c2w[:3, 3]), atol=1e-5)


def test_draw_pixels_is_uniform_over_all_pixels_of_images_of_several_sizes():
    import jax
    import jax.numpy as jnp

    from nerfkit.rays.cameras import draw_pixels

    sizes = jnp.asarray([(8, 6), (4, 3), (2, 1)])  # 48, 12 and 2 pixels
    img, i, j = (np.asarray(a) for a in draw_pixels(jax.random.PRNGKey(0), 62_000, sizes))
    share = np.bincount(img, minlength=3) / len(img)
    np.testing.assert_allclose(share, np.array([48, 12, 2]) / 62, atol=0.01)  # ~4 standard errors
    hw = np.asarray(sizes)[img]
    assert np.all((i >= 0) & (i < hw[:, 0]) & (j >= 0) & (j < hw[:, 1]))
    assert len(np.unique(np.stack([i, j], 1)[img == 0], axis=0)) == 48  # every pixel of the big image drawn
