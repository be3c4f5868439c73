"""Silhouette carving against a sphere's exact silhouettes."""

from __future__ import annotations

import numpy as np
import trimesh

from nerfkit.data.procedural.scene import intersect_sphere, look_at
from nerfkit.export.carve import MARGIN_PX, TOLERANCE_VIEWS, carve, outside_count
from nerfkit.rays.cameras import Camera

R = 0.5  # the sphere, at the origin
DIST, SIZE, FOCAL, SUPERSAMPLE = 4.0, 64, 80.0, 4
FOOTPRINT = (DIST + R) / FOCAL  # one pixel at the far side of the sphere, in units of length


def sphere_views(n: int = 12):
    """Poses, cameras and silhouettes [H, W] (exact pixel coverage > 1/2, SUPERSAMPLE^2 rays a pixel) of the sphere."""
    cam = Camera.pinhole(SIZE, SIZE, FOCAL)
    s = SUPERSAMPLE
    u, v = np.meshgrid((np.arange(SIZE * s) + 0.5) / s, (np.arange(SIZE * s) + 0.5) / s)
    poses, alphas = [], []
    for k in range(n):
        az, el = 2 * np.pi * k / n, np.radians(35.0 if k % 2 else -20.0)
        c2w = look_at(DIST * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]))
        d = np.stack([(u - cam.cx) / cam.fx, -(v - cam.cy) / cam.fy, -np.ones_like(u)], -1) @ c2w[:3, :3].T
        hit = np.isfinite(intersect_sphere(np.broadcast_to(c2w[:3, 3], d.shape), d, np.zeros(3), R))
        poses.append(c2w)
        alphas.append(hit.reshape(SIZE, s, SIZE, s).mean(axis=(1, 3)) > 0.5)
    return np.stack(poses), [cam] * n, alphas


def test_carving_pulls_an_oversized_sphere_onto_the_silhouettes_and_drops_a_floater():
    poses, cams, alphas = sphere_views()
    ball = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    unit = np.asarray(ball.vertices)
    faces = np.asarray(ball.faces)
    scales = np.where(np.arange(len(unit)) % 2 == 0, 1.04, 0.8) * R  # half 4% too big, half 1.8 px inside
    verts = unit * scales[:, None]
    # A floater: a small ball beside the sphere, where every view that sees it sees background.
    floater = unit * 0.05 + np.array([0.0, 0.0, 0.9])
    all_verts = np.concatenate([verts, floater])
    # A film from the sphere to the floater: one of its vertices stays outside, so it goes too.
    bridge = np.array([[faces[0, 0], faces[0, 1], len(unit)]])
    all_faces = np.concatenate([faces, faces + len(unit), bridge])
    # A wrong normal: tangent to the sphere, along which an outside vertex never gets in (the 26
    # cube directions must find the way).
    tangent = np.cross(unit, np.where(np.abs(unit[:, 2:]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]]))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    wrong = np.arange(len(unit)) % 4 == 0
    normals = np.concatenate([np.where(wrong[:, None], tangent, unit), unit])
    assert outside_count(floater, poses, cams, alphas).min() > 0
    before = outside_count(all_verts, poses, cams, alphas, MARGIN_PX)
    delta = FOOTPRINT / 4
    out, out_faces, stats = carve(all_verts, normals, all_faces, poses, cams, alphas, delta, 16, tolerance=0)
    # The floater is more than 16 delta from the hull in every direction: the faces using it go.
    assert stats["absent"] == len(floater) and stats["dropped_faces"] == len(faces) + 1
    assert len(out) == len(unit) and np.array_equal(out_faces, faces)
    # Every kept vertex is now on the object in every view that sees it...
    assert outside_count(out, poses, cams, alphas, MARGIN_PX).max() == 0
    r = np.linalg.norm(out, axis=1)
    # ... vertices that were inside did not move ...
    inside = before[: len(unit)] == 0
    assert np.array_equal(out[inside], verts[inside].astype(np.float32))
    assert inside.sum() >= len(unit) // 2
    # ... and the oversized ones moved inward onto the sphere: no deeper than one step plus the one pixel
    # that the per-pixel silhouette may lose at a contour and the margin, no further out than where they
    # started (12 views see a visual hull a little bigger than the sphere between them).
    moved = ~inside
    assert stats["moved_along_normal"] + stats["moved_otherwise"] == moved.sum() > len(unit) // 4
    assert stats["moved_otherwise"] >= (moved & wrong).sum() > 0
    assert np.all(r[moved] >= R - delta - (1 + MARGIN_PX) * FOOTPRINT - 1e-6) and np.all(r[moved] < 1.04 * R)
    print(f"carved radius / R: mean {r[moved].mean() / R:.4f}, min {r[moved].min() / R:.4f}, "
          f"max {r[moved].max() / R:.4f}")
    # On average within half a pixel plus the margin's diagonal of the sphere (a pixel here is 11% of R;
    # the per-pixel silhouette loses the part of a contour pixel that is less than half covered, the
    # margin keeps points sqrt(2) m from the edge; measured: 0.26 px inside without margin, 0.82 with 0.5 px).
    assert abs(r[moved].mean() - R) < (0.5 + np.sqrt(2) * MARGIN_PX) * FOOTPRINT


def test_outside_count_uses_the_lens():
    """A distorted camera projects through its lens: a point on a pixel's ray counts that pixel."""
    cam = Camera.from_colmap("SIMPLE_RADIAL", 64, 48, [60.0, 32.0, 24.0, 0.2])
    pose = look_at(np.array([0.0, -4.0, 0.0]))
    alpha = np.zeros((48, 64), bool)
    alpha[40, 60] = True  # one object pixel near the corner, where the distortion is strong
    x, y = cam.normalized_coords(np.array([60.5]), np.array([40.5]))
    d_cam = np.array([x[0], -y[0], -1.0])
    p = pose[:3, 3] + 3.0 * (pose[:3, :3] @ d_cam)
    assert outside_count(p[None], pose[None], [cam], [alpha])[0] == 0
    pin = Camera.pinhole(64, 48, 60.0)
    assert outside_count(p[None], pose[None], [pin], [alpha])[0] == 1  # without the lens: a background pixel


def test_one_wrong_mask_is_outvoted():
    """A view whose mask lost the object: the strict hull (t = 0) has nothing left, the default
    (TOLERANCE_VIEWS = 1) keeps the sphere; two wrong masks outvote it."""
    poses, cams, alphas = sphere_views()
    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    unit, faces = np.asarray(ball.vertices), np.asarray(ball.faces)
    verts = 0.8 * R * unit
    wrong = [np.zeros_like(alphas[0])] + alphas[1:]
    assert TOLERANCE_VIEWS == 1
    out, out_faces, stats = carve(verts, unit, faces, poses, cams, wrong, FOOTPRINT / 4, 8)
    assert np.array_equal(out, verts.astype(np.float32)) and np.array_equal(out_faces, faces)
    assert stats["outside"] == 0
    for t, masks in ((0, wrong), (1, [np.zeros_like(alphas[0])] * 2 + alphas[2:])):
        _, out_faces, stats = carve(verts, unit, faces, poses, cams, masks, FOOTPRINT / 4, 8, tolerance=t)
        assert len(out_faces) < len(faces) and stats["absent"] > 0
