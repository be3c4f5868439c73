"""The triangle rasteriser (export/raster.py) against brute force and exact depth, the texture bake
(export/texture.py) and the coverage scores (export/quality.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nerfkit.data.procedural.scene import look_at
from nerfkit.export.quality import coverage_scores, mesh_against_views
from nerfkit.export.raster import mesh_depth, rasterize
from nerfkit.export.texture import bake, textured_files, write_textured
from nerfkit.rays.cameras import Camera


def test_rasterize_matches_brute_force_point_in_triangle():
    rng = np.random.default_rng(0)
    h, w = 23, 31
    xy = rng.uniform(-5, 35, (30, 2))
    z = rng.uniform(1, 3, 30)
    faces = np.stack([rng.permutation(30)[:3] for _ in range(10)])
    face_id, bary, depth = rasterize(xy, z, faces, h, w)
    jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    best = np.full((h, w), np.inf)
    for f in faces:  # brute force: every pixel centre against every triangle, nearest 1/z-interpolated depth
        a, b, c = xy[f]
        area = np.cross(b - a, c - a)
        la = ((c[0] - b[0]) * (ii - b[1]) - (jj - b[0]) * (c[1] - b[1])) / area
        lb = ((a[0] - c[0]) * (ii - c[1]) - (jj - c[0]) * (a[1] - c[1])) / area
        lc = 1 - la - lb
        inside = (la >= 0) & (lb >= 0) & (lc >= 0)
        zq = 1 / (la / z[f[0]] + lb / z[f[1]] + lc / z[f[2]])
        best = np.where(inside & (zq < best), zq, best)
    np.testing.assert_array_equal(np.isfinite(depth), np.isfinite(best))
    np.testing.assert_allclose(depth[np.isfinite(best)], best[np.isfinite(best)], rtol=1e-5)
    assert (face_id >= 0).sum() == np.isfinite(best).sum() > 50
    ok = face_id >= 0
    np.testing.assert_allclose(bary[ok].sum(-1), 1.0, atol=1e-5)


def test_mesh_depth_of_a_plane_is_exact():
    """A square at z = -2 in front of a camera at the origin looking down -z: every covered pixel's
    z-depth is 2 (perspective-correct interpolation), and it covers the pixels its corners bound."""
    cam = Camera(width=40, height=30, fx=50.0, fy=50.0, cx=20.0, cy=15.0)
    verts = np.array([[-0.5, -0.3, -2], [0.5, -0.3, -2], [0.5, 0.3, -2], [-0.5, 0.3, -2]], float)
    verts[:, :2] += 0.013  # not on pixel edges
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    d = mesh_depth(verts, faces, np.eye(4), cam)
    cover = np.isfinite(d)
    np.testing.assert_allclose(d[cover], 2.0, rtol=1e-6)
    u = 50 * verts[[0, 2], 0] / 2 + 20
    v = -50 * verts[[2, 0], 1] / 2 + 15
    cols = (np.arange(40) + 0.5 > u[0]) & (np.arange(40) + 0.5 < u[1])
    rows = (np.arange(30) + 0.5 > v[0]) & (np.arange(30) + 0.5 < v[1])
    np.testing.assert_array_equal(cover, rows[:, None] & cols[None, :])
    # tilted: the depth of the plane z = -2 - 0.5 x at every covered pixel centre's ray
    tilted = verts.copy()
    tilted[:, 2] = -2 - 0.5 * tilted[:, 0]
    d = mesh_depth(tilted, faces, np.eye(4), cam)
    jj = np.arange(40)[None, :] + 0.5
    x_over_z = (jj - 20) / 50  # the ray's x / z-depth
    exact = 2 / (1 - 0.5 * x_over_z) * np.ones((30, 1))  # z = 2 + 0.5 x, x = x_over_z z
    np.testing.assert_allclose(d[np.isfinite(d)], exact[np.isfinite(d)], rtol=1e-5)


def test_coverage_scores_both_ways():
    sil = np.zeros((10, 10), bool)
    sil[2:8, 2:8] = True
    assert coverage_scores(sil, sil) == {"iou": 1.0, "precision": 1.0, "recall": 1.0}
    empty = coverage_scores(np.zeros_like(sil), sil)
    assert empty["iou"] == 0 and empty["recall"] == 0
    full = coverage_scores(np.ones_like(sil), sil)
    assert full["recall"] == 1 and full["iou"] == full["precision"] == pytest.approx(0.36)


def test_sphere_mesh_against_its_own_silhouettes():
    sphere = trimesh.creation.icosphere(4, radius=0.5)
    cam = Camera(width=48, height=48, fx=60.0, fy=60.0, cx=24.0, cy=24.0)
    poses = [look_at(3 * np.array([np.cos(a), np.sin(a), 0.3])) for a in (0.0, 2.0)]
    centres = [np.stack(np.meshgrid(np.arange(48) + 0.5, np.arange(48) + 0.5), -1) for _ in poses]
    # exact silhouette of the sphere: pixel centre rays within R of the centre
    sils = []
    for pose, c in zip(poses, centres):
        d = np.concatenate([(c[..., :1] - 24) / 60, -(c[..., 1:] - 24) / 60, -np.ones((48, 48, 1))], -1) @ pose[:3, :3].T
        o = pose[:3, 3]
        t = -(d @ o) / np.sum(d * d, -1)
        sils.append(np.linalg.norm(o + t[..., None] * d, axis=-1) < 0.5)
    out = mesh_against_views(np.asarray(sphere.vertices), np.asarray(sphere.faces), np.stack(poses), [cam, cam], sils)
    # the polyhedron lies inside the sphere: its silhouette misses a rim thinner than a pixel
    assert out["precision_min"] == 1.0 and out["iou_min"] > 0.95
    # A field whose silhouette is the sphere's scores its own IoU 1 and the mesh covers nearly all of it; a field
    # that also covers the left half of the image scores lower itself, and the mesh covers less of it.
    depth = [np.full((48, 48), 3.0)] * 2
    wide = [s | (np.arange(48)[None, :] < 24) for s in sils]
    for opacity, own in ((sils, 1.0), (wide, None)):
        scored = mesh_against_views(np.asarray(sphere.vertices), np.asarray(sphere.faces), np.stack(poses),
                                    [cam, cam], sils, depth, [o.astype(np.float32) for o in opacity], 0.01)
        if own:
            assert scored["field_iou_min"] == scored["field_recall_min"] == 1.0
            assert scored["recall_of_field_min"] == pytest.approx(out["recall_min"])
        else:
            assert scored["field_iou_mean"] < 0.7 and scored["field_recall_min"] == 1.0
            assert scored["recall_of_field_mean"] < 0.7


@pytest.mark.smoke  # xatlas, trimesh's glTF / OBJ writers and Pillow at their lowest allowed versions
def test_texture_bake_carries_the_colour_of_each_point(tmp_path):
    mesh = trimesh.creation.icosphere(3, radius=1.0)
    verts, faces = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces)
    normals = np.asarray(mesh.vertex_normals, np.float32)

    def colors_of(p, n):  # a smooth colour field of position
        return np.clip(0.5 + 0.5 * p, 0, 1)

    uv, f2, v2, image = bake(verts, normals, faces, 256, colors_of)
    assert f2.shape == faces.shape and len(uv) == len(v2) >= len(verts)
    # read the texture back at the centroid of every face: the colour of the centroid (to 8 bits and a
    # texel of colour gradient: 2 / 256 over a texel at most)
    h, w = image.shape[:2]
    cuv = uv[f2].mean(1)
    texel = image[np.clip(((1 - cuv[:, 1]) * h).astype(int), 0, h - 1), np.clip((cuv[:, 0] * w).astype(int), 0, w - 1)]
    want = colors_of(v2[f2].mean(1), None) * 255
    assert np.abs(texel - want).mean() < 4 and np.percentile(np.abs(texel - want), 99) < 16
    files = write_textured(tmp_path / "m.glb", v2, f2, uv, image)
    assert files == textured_files(tmp_path / "m.glb")
    back = trimesh.load(tmp_path / "m.glb", force="mesh")
    assert len(back.faces) == len(faces) and back.visual.material.baseColorTexture.size == (w, h)
    files = write_textured(tmp_path / "m.obj", v2, f2, uv, image)
    assert [f.name for f in files] == ["m.obj", "m.mtl", "m.png"] and all(f.is_file() for f in files)
    assert "m.png" in (tmp_path / "m.mtl").read_text()
    obj = trimesh.load(tmp_path / "m.obj", force="mesh")
    assert len(obj.faces) == len(faces) and obj.visual.uv.shape == (len(obj.vertices), 2)


def test_interior_pixels_leave_out_edges_and_depth_jumps():
    from nerfkit.export.quality import EDGE_PX, interior_pixels

    sil = np.zeros((40, 40), bool)
    sil[5:35, 5:35] = True
    depth = np.where(np.arange(40)[None, :] < 20, 2.0, 3.0) * np.ones((40, 1))
    inner = interior_pixels(sil, depth, tol=0.1)
    row = inner[20]
    # the silhouette's edge pixels (5, 34) and the jump's two sides (19, 20), each widened by EDGE_PX
    far = [j for j in range(40) if min(abs(j - 5), abs(j - 34), abs(j - 19), abs(j - 20)) > EDGE_PX]
    assert list(np.flatnonzero(row)) == far
    assert interior_pixels(sil, np.full((40, 40), 2.0), 0.1)[20, 20]  # no jump: the middle is interior
