"""Taubin smoothing of a mesh (export/surface.py: taubin_smooth): ripples go, the size stays."""

import numpy as np
import trimesh

from nerfkit.export.surface import taubin_smooth


def test_taubin_smoothing_takes_a_spheres_ripples_and_keeps_its_radius():
    sphere = trimesh.creation.icosphere(4, radius=1.0)
    verts = np.asarray(sphere.vertices)
    faces = np.asarray(sphere.faces)
    rng = np.random.default_rng(0)
    noisy = verts * (1.0 + 0.02 * rng.standard_normal(len(verts)))[:, None]  # 2% radial ripple

    def normal_error(v):  # the faces' normals against the sphere's (radial) normal at their centres, degrees
        m = trimesh.Trimesh(v, faces, process=False)
        c = m.triangles_center / np.linalg.norm(m.triangles_center, axis=1, keepdims=True)
        return np.degrees(np.arccos(np.clip(np.sum(m.face_normals * c, axis=1), -1, 1))).mean()

    smooth = taubin_smooth(noisy, faces, 20)
    assert smooth.shape == noisy.shape and np.array_equal(taubin_smooth(noisy, faces, 0), noisy)
    assert normal_error(smooth) < 0.4 * normal_error(noisy)
    radius = np.linalg.norm(smooth, axis=1)
    assert abs(radius.mean() - 1.0) < 0.005 and radius.std() < 0.5 * np.linalg.norm(noisy, axis=1).std()
