"""Gaussians to and from the Inria 3DGS .ply layout (what SuperSplat, Spark, gsplat, nerfstudio, Brush open).

One binary little-endian `vertex` element with float32 properties, in this order:

    x y z                  mean
    nx ny nz               zeros (unused normals)
    f_dc_0 f_dc_1 f_dc_2   band-0 SH coefficient of R, G, B (colour = 0.2821 f_dc + 0.5)
    f_rest_0 .. f_rest_44  bands 1..3, channel-major: f_rest_{c * 15 + k} = coefficient k + 1 of channel c
                           (all R coefficients, then G, then B); fewer when the degree is lower
    opacity                logit (the viewer applies the sigmoid)
    scale_0 scale_1 scale_2   log scales
    rot_0 rot_1 rot_2 rot_3   quaternion w, x, y, z (the viewer normalises)

These are exactly gaussians.py's parameters, so the file is written and read without conversion
except the channel-major reordering of f_rest. `transform` (a 4 x 4 similarity) moves the
Gaussians on the way out or in (transform.py: positions, rotations, log scales and the SH
coefficients), e.g. invert_similarity(SceneData.transform) to write in the capture's coordinates.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.models.splat.formats import N_REST, REST_OF_DEGREE, SplatFormat
from nerfkit.models.splat.transform import transform_gaussians

def _rest_count(names) -> int:
    n = sum(1 for k in names if k.startswith("f_rest_"))
    if n % 3 or n // 3 not in REST_OF_DEGREE:
        raise ValueError(f"{n} f_rest properties: not 3 x (0, 3, 8 or 15) SH coefficients")
    return n // 3


def export_ply(path: str | Path, params: dict, transform: np.ndarray | None = None, sh_degree: int = 3) -> Path:
    """Write Gaussians (numpy dict, gaussians.py's layout) to an Inria-layout .ply; returns the path.

    transform: optional [4, 4] similarity applied first. sh_degree: bands written (0..3; 45
    f_rest properties at 3)."""
    from plyfile import PlyData, PlyElement

    p = {k: np.asarray(v) for k, v in params.items()}
    if transform is not None:
        p = transform_gaussians(p, transform)
    n = len(p["means"])
    k_rest = (sh_degree + 1) ** 2 - 1
    rest = np.zeros((n, k_rest, 3), np.float32)
    rest[:, : min(k_rest, p["sh_rest"].shape[1])] = p["sh_rest"][:, :k_rest]
    columns = [p["means"], np.zeros((n, 3), np.float32), p["sh_dc"].reshape(n, 3),
               rest.transpose(0, 2, 1).reshape(n, 3 * k_rest), p["opacity"].reshape(n, 1), p["log_scales"], p["quats"]]
    names = (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
             + [f"f_rest_{i}" for i in range(3 * k_rest)]
             + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])
    data = np.concatenate([np.asarray(c, np.float32).reshape(n, -1) for c in columns], axis=1)
    vertex = np.empty(n, dtype=[(name, "<f4") for name in names])
    for i, name in enumerate(names):
        vertex[name] = data[:, i]
    path = Path(path)
    PlyData([PlyElement.describe(vertex, "vertex")], byte_order="<").write(str(path))
    return path


def import_ply(path: str | Path, transform: np.ndarray | None = None) -> dict:
    """Read an Inria-layout .ply into gaussians.py's parameters (numpy float32; SH bands the file lacks are 0).

    transform: optional [4, 4] similarity applied after reading (e.g. SceneData.transform to bring
    capture coordinates into nerfkit's normalised frame)."""
    p, _ = read_ply(path)
    return transform_gaussians(p, transform) if transform is not None else p


def read_ply(path: str | Path) -> tuple[dict, int]:
    """(Gaussians, SH degree) of a splat .ply: the properties are found by name, in any order and of any
    numeric type (3DGS, gsplat, Brush, SuperSplat and nerfstudio order them differently; normals optional)."""
    from plyfile import PlyData

    ply = PlyData.read(str(path))
    if "vertex" not in [e.name for e in ply.elements]:
        raise ValueError("no vertex element (a compressed or mesh .ply?)")
    v = ply["vertex"]
    names = v.data.dtype.names
    missing = [k for k in ("x", "f_dc_0", "opacity", "scale_0", "rot_0") if k not in names]
    if missing:
        raise ValueError(f"{path}: not a Gaussian splat .ply (no {', '.join(missing)} property)")

    def cols(keys):
        return np.stack([np.asarray(v[k], np.float32) for k in keys], axis=-1)

    n = len(v.data)
    k_rest = _rest_count(names)
    rest = np.zeros((n, N_REST, 3), np.float32)
    if k_rest:
        rest[:, :k_rest] = cols([f"f_rest_{i}" for i in range(3 * k_rest)]).reshape(n, 3, k_rest).transpose(0, 2, 1)
    p = {"means": cols(["x", "y", "z"]), "log_scales": cols(["scale_0", "scale_1", "scale_2"]),
         "quats": cols(["rot_0", "rot_1", "rot_2", "rot_3"]), "opacity": np.asarray(v["opacity"], np.float32),
         "sh_dc": cols(["f_dc_0", "f_dc_1", "f_dc_2"])[:, None, :], "sh_rest": rest}
    return p, {0: 0, 3: 1, 8: 2, 15: 3}[k_rest]


FORMAT = SplatFormat(
    name="Inria 3DGS .ply", opens="SuperSplat, Spark, GaussianSplats3D, gsplat, nerfstudio, Brush, viser", max_sh=3,
    write=lambda path, g, degree: export_ply(path, g, sh_degree=degree), read=read_ply)
