"""Tests for the procedural scene's exact surfaces (nerfkit.data.procedural.surfaces)."""

import math

import numpy as np

from nerfkit.data.procedural import scene
from nerfkit.data.procedural.surfaces import crease_distance, signed_distance, surface_normal


def traced_points(size: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Points [N, 3] where rays of two cameras hit the scene, and the hit normals' reference: the ray tracer."""
    focal = 0.5 * size / math.tan(0.5 * scene.CAMERA_ANGLE_X)
    pts = []
    for c2w in (scene.orbit_pose(0.5, 0.5), scene.orbit_pose(3.5, 1.0)):
        o, d = scene.camera_rays(c2w, size, size, focal)
        _, alpha, t = scene.trace(o, d)
        hit = alpha > 0.5
        pts.append(o[hit] + t[hit][:, None] * d[hit])
    return np.concatenate(pts)


def test_traced_hits_lie_on_the_surface_with_outward_normals():
    p = traced_points()
    assert len(p) > 500
    assert np.abs(signed_distance(p)).max() < 1e-5
    # Away from creases, a step along the normal leaves the solids by that step (near one, a concave corner
    # may be nearer).
    p = p[crease_distance(p) > 0.02]
    np.testing.assert_allclose(signed_distance(p + 0.01 * surface_normal(p)), 0.01, atol=1e-6)


def test_crease_distance_on_the_box_top():
    # The box's top face z = BOX_MAX_z spans [0.15, 0.75] x [0.05, 0.65]: at its centre the nearest edge is
    # 0.3 away; walking towards x = 0.75 the distance falls linearly to 0 at the edge.
    zt = scene.BOX_MAX[2]
    xs = np.linspace(0.45, 0.75, 7)
    p = np.stack([xs, np.full_like(xs, 0.35), np.full_like(xs, zt)], -1)
    np.testing.assert_allclose(crease_distance(p), 0.75 - xs, atol=1e-9)


def test_crease_distance_of_the_ground_is_its_distance_to_what_stands_on_it():
    # On the ground's top, far from its rim, the nearest crease is where the box meets it: at (0, 0) the box
    # corner (0.15, 0.05) is sqrt(0.15^2 + 0.05^2) away; near the rim, the rim.
    zg = scene.GROUND_Z_RANGE[1]
    d = crease_distance(np.array([[0.0, 0.0, zg], [scene.GROUND_RADIUS - 0.02, 0.0, zg]]))
    np.testing.assert_allclose(d, [math.hypot(0.15, 0.05), 0.02], atol=1e-9)


def test_spheres_have_no_edges():
    # The big sphere's top is a smooth surface: its nearest crease is another solid, over half a unit away.
    top = scene.BIG_SPHERE_CENTER + np.array([0.0, 0.0, scene.BIG_SPHERE_RADIUS])
    assert crease_distance(top[None])[0] > 0.5
    p = traced_points()
    d = crease_distance(p)
    assert np.all(d >= 0) and np.mean(d < 0.05) < 0.5 < np.mean(d < 0.5)
