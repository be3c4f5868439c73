"""A splat file whose colour comes mostly from SH bands 1-3 (test_ply.gaussians), and two cameras on it, in front
and from behind: the view-dependent tests of the web renderers (test_spark.py, test_playcanvas.py)."""

import numpy as np
from test_ply import gaussians

from nerfkit.models.splat.formats import read_gaussians, splat_format
from nerfkit.models.splat.gaussians import render
from nerfkit.rays.cameras import Camera, look_at

EYES = ([1.0, 1.5, 3.0], [-2.5, 0.5, -2.0])


def sh_scene(path, size: int) -> tuple[dict, Camera, list[np.ndarray]]:
    """Write the Gaussians to `path` (its extension's format, SH degree 3) and read them back: (Gaussians, a
    size x size pinhole camera, its poses looking at the origin from EYES, +y up)."""
    splat_format(path).write(path, gaussians(), 3)
    g, degree, _ = read_gaussians(path)
    assert degree == 3
    poses = [look_at(np.asarray(eye), np.zeros(3), up=np.array([0.0, 1.0, 0.0])) for eye in EYES]
    return g, Camera.pinhole(size, size, 220.0), poses


def degree_zero(g: dict, c2w: np.ndarray, camera: Camera) -> np.ndarray:
    """nerfkit's render of `g` without its view dependence (SH degree 0), clipped to [0, 1]."""
    return np.clip(render(g, c2w, camera, sh_degree=0, depth=False)["rgb"], 0, 1)
