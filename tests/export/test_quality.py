"""export/quality.py's depth, normal and roughness measures, both ways: a field that agrees with the mesh scores
full marks, one that does not scores low (the records' smoothing defaults were chosen with these numbers)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nerfkit.data.procedural.scene import look_at
from nerfkit.export.quality import mesh_against_views, mesh_roughness
from nerfkit.export.raster import mesh_depth
from nerfkit.rays.cameras import Camera

TOL = 0.02


@pytest.fixture(scope="module")
def sphere_views():
    """A sphere of radius 0.5 seen from two cameras 3 units away at 160 px, with its own depth as the field's."""
    sphere = trimesh.creation.icosphere(4, radius=0.5)
    verts, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    cam = Camera(width=160, height=160, fx=200.0, fy=200.0, cx=80.0, cy=80.0)
    poses = np.stack([look_at(3 * np.array([np.cos(a), np.sin(a), 0.3])) for a in (0.0, 2.0)])
    depth = [mesh_depth(verts, faces, p, cam) for p in poses]
    sils = [np.isfinite(d) for d in depth]
    field = [np.where(s, d, 10.0).astype(np.float32) for s, d in zip(sils, depth)]  # the room behind at 10
    return verts, faces, poses, [cam, cam], sils, field


def scored(sphere_views, field, median):
    verts, faces, poses, cams, sils, _ = sphere_views
    return mesh_against_views(verts, faces, poses, cams, sils, field, [s.astype(np.float32) for s in sils], TOL,
                              median)


def test_a_field_that_is_the_mesh_agrees_everywhere(sphere_views):
    field = sphere_views[-1]
    out = scored(sphere_views, field, field)
    assert out["iou_min"] == 1.0 and out["field_iou_min"] == 1.0
    assert out["depth_within_tol_min"] == out["depth_within_tol_median_min"] == 1.0
    assert out["depth_within_tol_interior_min"] == 1.0
    assert min(v["interior_pixels"] for v in out["views"]) > 0.5 * np.pi * (0.5 * 200 / 3) ** 2
    # the depth map's normals span NORMAL_STEP pixels either side, a few facets of the polyhedron
    assert out["normals_within_deg_min"] > 0.95 and out["normal_median_deg_mean"] < 4.0


def test_a_field_behind_the_mesh_or_flat_disagrees(sphere_views):
    field, sils = sphere_views[-1], sphere_views[4]
    behind = [np.where(s, f + 3 * TOL, f) for s, f in zip(sils, field)]
    out = scored(sphere_views, behind, behind)
    assert out["depth_within_tol_mean"] == out["depth_within_tol_median_mean"] == 0.0
    assert out["normals_within_deg_min"] > 0.95  # moved back, not turned: the normals still agree
    flat = [np.where(s, 3.0, f).astype(np.float32) for s, f in zip(sils, field)]  # a disc facing the camera
    out = scored(sphere_views, field, flat)
    # a sphere's normals lie within 10 degrees of the view axis on sin^2(10 deg) = 3% of its disc
    assert out["normals_within_deg_mean"] < 0.1 and out["normal_median_deg_mean"] > 30.0
    assert out["depth_within_tol_mean"] == 1.0  # the depth the mesh is scored against is the field's, not the median


def test_mesh_roughness_sees_crumples_and_specks():
    sphere = trimesh.creation.icosphere(4, radius=0.5)
    verts, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    smooth = mesh_roughness(verts, faces)
    assert smooth["pieces"] == 1 and smooth["small_piece_faces"] == 0.0 and smooth["dihedral_median_deg"] < 6.0
    bumps = 1 + 0.05 * np.random.default_rng(0).standard_normal((len(verts), 1))
    assert mesh_roughness(verts * bumps, faces)["dihedral_median_deg"] > 3 * smooth["dihedral_median_deg"]
    speck = trimesh.creation.icosphere(0, radius=0.01)
    both = trimesh.util.concatenate([sphere, speck.apply_translation([2.0, 0, 0])])
    out = mesh_roughness(np.asarray(both.vertices), np.asarray(both.faces))
    assert out["pieces"] == 2 and out["small_piece_faces"] == pytest.approx(20 / len(both.faces))
