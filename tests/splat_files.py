"""Splat files as other tools write them (for the format and import tests)."""

import numpy as np
from plyfile import PlyData, PlyElement


def gsplat_like_ply(path, p, degree=1):
    """A .ply laid out as gsplat's exporter writes it: no normals, float32, x y z f_dc f_rest opacity scale rot."""
    n, k = len(p["means"]), (degree + 1) ** 2 - 1
    cols = {"x": p["means"][:, 0], "y": p["means"][:, 1], "z": p["means"][:, 2]}
    cols |= {f"f_dc_{c}": p["sh_dc"][:, 0, c] for c in range(3)}
    cols |= {f"f_rest_{c * k + j}": p["sh_rest"][:, j, c] for c in range(3) for j in range(k)}
    cols |= {"opacity": p["opacity"]} | {f"scale_{i}": p["log_scales"][:, i] for i in range(3)}
    cols |= {f"rot_{i}": p["quats"][:, i] for i in range(4)}
    v = np.empty(n, [(name, "<f4") for name in cols])
    for name, col in cols.items():
        v[name] = col
    PlyData([PlyElement.describe(v, "vertex")]).write(str(path))
