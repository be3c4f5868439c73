"""TSDF fusion (export/tsdf.py) on exact depth maps of a sphere, and the mesh helpers it feeds.

The views are ideal pinhole cameras 3 units from a sphere of radius R = 0.5 at the origin; each
pixel's depth is the exact z-depth of its centre ray's hit (opacity 1) or nothing (opacity 0).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nerfkit.data.procedural.scene import look_at
from nerfkit.export import tsdf
from nerfkit.export.carve import pixel_footprint
from nerfkit.export.surface import closed_and_manifold, drop_specks
from nerfkit.rays.cameras import Camera

R, SIZE, FOCAL, BOUND = 0.5, 64, 70.0, 1.0


def exact_view(c2w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(z-depth [H, W], opacity [H, W]) of the sphere seen by the camera at c2w (pixel centres)."""
    j, i = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    d_cam = np.stack([(j - SIZE / 2) / FOCAL, -(i - SIZE / 2) / FOCAL, -np.ones_like(j)], -1)  # z = -1: t is z-depth
    d = d_cam @ c2w[:3, :3].T
    o = c2w[:3, 3]
    a, b, c = np.sum(d * d, -1), 2 * d @ o, o @ o - R * R
    disc = b * b - 4 * a * c
    hit = disc > 0
    t = (-b - np.sqrt(np.where(hit, disc, 0))) / (2 * a)
    return np.where(hit, t, 100.0).astype(np.float32), hit.astype(np.float32)


def cameras(elevations_deg, n_azimuth: int) -> np.ndarray:
    poses = []
    for el in np.radians(elevations_deg):
        for az in np.linspace(0, 2 * np.pi, n_azimuth, endpoint=False) + el:
            poses.append(look_at(3.0 * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])))
    return np.stack(poses)


def fused_volume(poses: np.ndarray, res: int, watertight: bool):
    """(F, known, h, (c2w, intrinsics, depth, opacity)) fused from the exact views at poses."""
    views = [exact_view(p) for p in poses]
    depth, opac = np.stack([v[0] for v in views]), np.stack([v[1] for v in views])
    intr = np.tile([FOCAL, FOCAL, SIZE / 2, SIZE / 2], (len(poses), 1)).astype(np.float32)
    axis = np.linspace(-BOUND, BOUND, res, dtype=np.float32)
    h = float(axis[1] - axis[0])
    tau = tsdf.truncation(h, pixel_footprint(poses, [Camera(SIZE, SIZE, FOCAL, FOCAL, SIZE / 2, SIZE / 2)] * len(poses)))
    f, known = tsdf.tsdf_volume(*tsdf.fuse_grid(axis, poses, intr, depth, opac, tau), watertight)
    return f, known, h, (poses.astype(np.float32), intr, depth, opac)


def fused(poses: np.ndarray, res: int, watertight: bool):
    f, known, h, _ = fused_volume(poses, res, watertight)
    return tsdf.zero_surface(f, known, BOUND, watertight), h


def test_the_chosen_level_removes_the_fusions_inward_bias_on_exact_depth():
    """On exact depth maps the fused zero F = 0 lies inside the sphere: a grid point just inside a view's
    silhouette whose pixel centre misses the sphere votes a full +1, one just outside gets a small
    s / tau (measured: -0.14 of a pixel's footprint p on average). best_level, which scores each
    candidate surface by its depth agreement with the views (both ways: pixels where mesh or field is),
    picks a level whose surface has no bias (|mean r - R| < 0.05 p) and a smaller error; a volume shifted
    by 0.2 gets its level 0.2 higher; an empty mesh scores 0, and so does a level the volume never reaches."""
    f, known, h, views = fused_volume(cameras([-60, -20, 20, 60], 6), 64, False)
    p = 2.5 / FOCAL
    level, scores = tsdf.best_level(f, known, BOUND, *views)
    r0 = np.linalg.norm(tsdf.zero_surface(f, known, BOUND, False, 0.0)[0], axis=1) - R
    r = np.linalg.norm(tsdf.zero_surface(f, known, BOUND, False, level)[0], axis=1) - R
    assert r0.mean() < -0.1 * p  # the bias this corrects
    assert abs(r.mean()) < 0.05 * p and np.abs(r).mean() < 0.8 * np.abs(r0).mean()
    assert scores[level] > scores[0.0]
    shifted, _ = tsdf.best_level(np.clip(f + 0.2, -1.0, 1.0), known, BOUND, *views)
    assert abs(shifted - (level + 0.2)) <= 0.05
    assert tsdf.depth_iou(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64), *views, 0.02) == 0.0
    # candidate levels outside the fused values (a thin object never reaches F = -0.2) score 0, not a crash
    thin, thin_scores = tsdf.best_level(np.clip(f, -0.15, 1.0), known, BOUND, *views)
    assert thin_scores[-0.2] == 0.0 and thin > -0.15


def test_view_terms_free_surface_and_hidden_points():
    c2w = look_at(np.array([3.0, 0.0, 0.0]))
    depth, opac = exact_view(c2w)
    intr = np.array([FOCAL, FOCAL, SIZE / 2, SIZE / 2], np.float32)
    tau = 0.1
    x = np.array([[0.55, 0, 0], [0.5, 0, 0], [0.45, 0, 0], [0, 0, 0], [0, 0.9, 0], [3.5, 0, 0]], np.float32)
    wf, w, seen = (np.asarray(a) for a in tsdf.view_terms(x, c2w, intr, depth, opac, tau))
    # in front of the surface (s = 0.05 -> f = 0.5), on it, behind it (f = -0.5 at half the weight: the ramp
    # 1 + s / tau behind the surface), hidden deep inside (no weight), beside the sphere on a background pixel
    # (free: +1), behind the camera (not in the image)
    np.testing.assert_allclose(w, [1, 1, 0.5, 0, 1, 0], atol=0.01)
    # The depth is read at the pixel centre, half a pixel (0.018 units at z = 2.5) off the pole, where the
    # sphere is (0.018)^2 / 2R = 3e-4 farther; 1e-3 in depth is 0.01 in f = s / tau.
    np.testing.assert_allclose(wf, [0.5, 0.0, -0.25, 0, 1, 0], atol=0.01)
    np.testing.assert_array_equal(seen, [1, 1, 1, 1, 1, 0])


@pytest.mark.parametrize("watertight", [False, True])
def test_sphere_seen_from_everywhere_is_recovered_closed(watertight):
    poses = cameras([-60, -20, 20, 60], 6)
    (verts, faces), h = fused(poses, 64, watertight)
    r = np.linalg.norm(verts, axis=1)
    # Accuracy: each grid point reads the depth of the pixel it falls in, whose centre ray is up to half a
    # pixel away (one pixel spans p = z / f = 0.036 units at the sphere, more than a cell h = 0.032): on
    # the sloped parts of the sphere that is a fraction of p (measured: mean 0.16 p, max 0.47 p).
    p = 2.5 / FOCAL
    assert np.abs(r - R).mean() < 0.25 * p and np.abs(r - R).max() < 0.6 * p
    # Completeness: every direction of the sphere has a vertex within a cell.
    dirs = trimesh.creation.icosphere(3).vertices
    gap = np.min(np.linalg.norm(R * dirs[:, None] - verts[None], axis=-1), axis=1)
    assert gap.max() < h
    assert closed_and_manifold(verts, faces)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    # outward normals: a positive volume; marching cubes cuts the corners of a convex surface (measured 0.95-0.97)
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * R**3, rel=0.06)


def test_unseen_underside_stays_open_unless_watertight():
    poses = cameras([35, 70], 8)  # from above only: no ray reaches the underside of the sphere
    (verts, faces), h = fused(poses, 64, False)
    assert not closed_and_manifold(verts, faces)
    top = verts[verts[:, 2] > 0.2]
    assert len(top) > 100 and np.abs(np.linalg.norm(top, axis=1) - R).max() < 0.6 * 2.5 / FOCAL  # seen: right
    (w_verts, w_faces), _ = fused(poses, 64, True)
    assert closed_and_manifold(w_verts, w_faces)
    # closed below by what every view saw hidden behind the sphere (the visual hull's cone), never above it
    assert w_verts[:, 2].max() < R + h and w_verts[:, 2].min() < -R


def test_drop_specks_keeps_pieces_by_size_not_share():
    big = trimesh.creation.icosphere(2, radius=1.0)
    small = trimesh.creation.icosphere(1, radius=0.2)
    small.vertices += [3, 0, 0]
    speck = trimesh.creation.icosphere(0, radius=0.01)
    speck.vertices += [0, 3, 0]
    m = trimesh.util.concatenate([big, small, speck])
    v, f, dropped = drop_specks(np.asarray(m.vertices), np.asarray(m.faces), size=0.1)
    assert dropped == 1 and len(f) == len(big.faces) + len(small.faces) and len(v) == len(big.vertices) + len(
        small.vertices)


def exact_plate_view(c2w: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(z-depth [H, W], opacity [H, W]) of the box |x_i| <= half_i seen by the camera at c2w (slab test)."""
    j, i = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    d = np.stack([(j - SIZE / 2) / FOCAL, -(i - SIZE / 2) / FOCAL, -np.ones_like(j)], -1) @ c2w[:3, :3].T
    o = c2w[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - o) / d, (half - o) / d
    near, far = np.minimum(t1, t2).max(-1), np.maximum(t1, t2).min(-1)
    hit = near < far
    return np.where(hit, near, 100.0).astype(np.float32), hit.astype(np.float32)


def test_a_wall_thinner_than_the_truncation_keeps_its_faces():
    """A plate of thickness t = 0.05 < tau (0.095), seen from above and below. A point e above its top face
    is e in front of the top views' surface (f = e / tau) and t + e behind the bottom views' (f = -(t + e) /
    tau): with full weight behind the surface the two cancel only at e = tau - t (0.045: the plate comes out
    0.14 thick); with the ramp w = 1 + s / tau behind it, where e = (1 - (t + e) / tau)(t + e), e* = 0.019
    for views straight along the normal (oblique views see a longer way behind the face, so less)."""
    t, half = 0.05, np.array([0.5, 0.5, 0.025])
    poses = cameras([-70, -45, 45, 70], 6)
    views = [exact_plate_view(p, half) for p in poses]
    depth, opac = np.stack([v[0] for v in views]), np.stack([v[1] for v in views])
    intr = np.tile([FOCAL, FOCAL, SIZE / 2, SIZE / 2], (len(poses), 1)).astype(np.float32)
    axis = np.linspace(-BOUND, BOUND, 64, dtype=np.float32)
    tau = tsdf.truncation(float(axis[1] - axis[0]), pixel_footprint(poses, [Camera(SIZE, SIZE, FOCAL, FOCAL, SIZE / 2,
                                                                                       SIZE / 2)] * len(poses)))
    assert tau > t
    verts, _ = tsdf.zero_surface(*tsdf.tsdf_volume(*tsdf.fuse_grid(axis, poses, intr, depth, opac, tau), False),
                                 BOUND, False, 0.0)
    e = np.linspace(0, tau - t, 10001)
    e_star = e[np.argmin(np.abs(e - (1 - (t + e) / tau) * (t + e)))]
    middle = verts[(np.abs(verts[:, 0]) < 0.3) & (np.abs(verts[:, 1]) < 0.3)]
    top, bottom = middle[middle[:, 2] > 0, 2], middle[middle[:, 2] < 0, 2]
    assert len(top) > 100 and len(bottom) > 100
    assert 0 <= top.mean() - t / 2 < e_star and 0 <= -t / 2 - bottom.mean() < e_star


def face_normal_errors(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Angles (degrees) between the sphere's true normals and the mesh's face normals, at points spread over the
    surface by area."""
    mesh = trimesh.Trimesh(verts, faces, process=False)
    pts, fid = trimesh.sample.sample_surface(mesh, 20000, seed=0)
    true = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(mesh.face_normals[fid] * true, 1), -1, 1)))


def test_smoothing_the_fused_volume_by_half_a_pixel_removes_the_pixel_ripples():
    """Each view's depth is read once per pixel, so F carries ripples of a pixel's footprint p, which a grid finer
    than p turns into facets: on exact depth at 128^3 (h = 0.44 p) the faces' normals are off by more than 10
    degrees on most of the sphere (measured: within 10 degrees on 28%). Blurred by SMOOTH_PIXELS p
    (smooth_volume), within 10 degrees on 100%, and the radius no worse (mean error 0.09 p -> 0.04 p)."""
    f, known, h, views = fused_volume(cameras([-60, -20, 20, 60], 6), 128, False)
    p = 2.5 / FOCAL
    raw = tsdf.zero_surface(f, known, BOUND, False, 0.2)
    smooth = tsdf.zero_surface(tsdf.smooth_volume(f, known, tsdf.SMOOTH_PIXELS * p / h), known, BOUND, False, 0.2)
    assert np.mean(face_normal_errors(*raw) < 10) < 0.5
    assert np.mean(face_normal_errors(*smooth) < 10) > 0.95
    err_raw = np.abs(np.linalg.norm(raw[0], axis=1) - R).mean()
    err_smooth = np.abs(np.linalg.norm(smooth[0], axis=1) - R).mean()
    assert err_smooth < 0.06 * p and err_smooth < err_raw
    assert len(smooth[1]) > 0.5 * len(raw[1])  # still the whole sphere, not a fragment of it
