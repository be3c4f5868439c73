"""Bilateral normal filtering of a mesh (export/denoise.py): flat faces flattened, edges kept, the rim held."""

import numpy as np
import trimesh

from nerfkit.export.denoise import bilateral_smooth, face_geometry, filter_normals, incidence
from nerfkit.export.surface import taubin_smooth


def noisy_cube(noise: float, seed: int = 0):
    """A unit cube's surface in triangles about 0.05 across, each vertex moved by `noise` (a normal per axis)."""
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    v, f = trimesh.remesh.subdivide_to_size(box.vertices, box.faces, 0.05)
    mesh = trimesh.Trimesh(v, f)
    mesh.merge_vertices()
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    return v + noise * np.random.default_rng(seed).standard_normal(v.shape), f


def cube_normals_within(verts, faces, deg: float = 10.0) -> float:
    """The share of faces whose normal is within `deg` of the normal of the cube's side nearest their centre."""
    c, n, _ = face_geometry(verts, faces)
    axis = np.argmax(np.abs(c), axis=1)
    rows = np.arange(len(c))
    truth = np.zeros_like(c)
    truth[rows, axis] = np.sign(c[rows, axis])
    return float(np.mean(np.sum(n * truth, axis=1) >= np.cos(np.radians(deg))))


def test_bilateral_filtering_flattens_a_cubes_sides_and_keeps_its_edges():
    """After Taubin's filter, the cube's edges are rounded (its faces there lean between two sides); bilateral
    filtering lays them back onto the sides. Without the range weight (sigma_r far above any normal difference) the
    filter is a plain average of normals and rounds the edges further."""
    noisy, faces = noisy_cube(0.01)
    taubin = taubin_smooth(noisy, faces, 20)
    both = bilateral_smooth(taubin, faces, 40)
    plain = bilateral_smooth(taubin, faces, 40, sigma_r=2.0)
    assert cube_normals_within(noisy, faces) < 0.2
    assert cube_normals_within(taubin, faces) < 0.9
    assert cube_normals_within(both, faces) > 0.99
    assert cube_normals_within(plain, faces) < cube_normals_within(taubin, faces)
    off_side = lambda v: np.abs(np.abs(v).max(axis=1) - 0.5).mean()  # noqa: E731  (distance to the cube's sides)
    assert off_side(both) < 0.5 * off_side(taubin) and both.dtype == np.float32 and both.shape == noisy.shape
    assert np.array_equal(bilateral_smooth(noisy, faces, 0), noisy)


def test_the_normal_filter_is_a_weighted_mean_of_neighbours_that_point_the_same_way():
    """Two triangles folded at 90 degrees keep their normals (each neighbour weighs exp(-25) of itself); folded at 5
    degrees they meet at the mean normal, since the range weight is then nearly 1."""
    for fold, expect_same in ((90.0, True), (5.0, False)):
        a = np.radians(fold)
        verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -np.cos(a), np.sin(a)]], np.float64)
        faces = np.array([[0, 1, 2], [0, 3, 1]])
        inc = incidence(faces, 4)
        c, n, area = face_geometry(verts, faces)
        out = filter_normals(c, n, area, inc @ inc.T, rounds=10)
        assert np.allclose(np.linalg.norm(out, axis=1), 1.0)
        if expect_same:
            assert np.allclose(out, n, atol=1e-6)
        else:
            mean = (n[0] + n[1]) / np.linalg.norm(n[0] + n[1])
            assert np.allclose(out, mean, atol=1e-3)


def test_an_open_meshs_rim_stays_and_its_inside_flattens():
    """A bumpy open square: its rim vertices do not move, its interior comes closer to the plane."""
    n = 21
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    verts = np.stack([x.ravel(), y.ravel(), 0.003 * np.random.default_rng(1).standard_normal(n * n)], axis=1)
    q = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([q, q + 1, q + n], 1), np.stack([q + 1, q + n + 1, q + n], 1)])
    out = bilateral_smooth(verts, faces, 20)
    rim = (x.ravel() == 0) | (x.ravel() == 1) | (y.ravel() == 0) | (y.ravel() == 1)
    assert np.allclose(out[rim], verts[rim], atol=1e-6)
    assert np.abs(out[~rim, 2]).mean() < 0.5 * np.abs(verts[~rim, 2]).mean()
