"""Gaussians to and from antimatter15's .splat: 32 bytes a Gaussian, no header, no spherical harmonics (what
antimatter15/splat, Spark and GaussianSplats3D open).

One record per Gaussian, little-endian, in the capture's coordinates (the .ply's):

    position  3 x float32      mu
    scale     3 x float32      e^s (linear, not log)
    colour    4 x uint8        round(255 clip(SH_C0 sh_dc + 0.5)), round(255 sigmoid(opacity))
    rotation  4 x uint8        round(128 q / |q| + 128), w first (clipped to 0..255)

The view-dependent bands are dropped: colour is what the Gaussian shows from every side (its degree-0
part), and colours outside [0, 1] are clipped. Records are written largest first (e^(s_0 + s_1 + s_2)
sigmoid(opacity), descending), the order antimatter15's converter writes and progressive loaders expect.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.models.splat.formats import N_REST, SH_C0, SplatFormat, base_colour, unit_quats

RECORD = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rotation", "u1", 4)])
_ALPHA_EPS = 0.5 / 255  # read: opacity bytes 0 and 255 as sigmoid^-1 of half a step inside


def write_splat(path: str | Path, g: dict, sh_degree: int = 0) -> None:
    """Write Gaussians (capture coordinates) as .splat records (sh_degree is ignored: the format has none)."""
    means = np.asarray(g["means"], np.float32)
    log_scales = np.asarray(g["log_scales"], np.float64)
    alpha = 1.0 / (1.0 + np.exp(-np.asarray(g["opacity"], np.float64)))
    colour = base_colour(g["sh_dc"])
    q = unit_quats(np.asarray(g["quats"], np.float64))
    order = np.argsort(-(np.exp(log_scales.sum(axis=1)) * alpha), kind="stable")
    rec = np.empty(len(means), RECORD)
    rec["position"] = means[order]
    rec["scale"] = np.exp(log_scales[order])
    rec["rgba"] = np.round(255 * np.concatenate([colour, alpha[:, None]], axis=1)[order])
    rec["rotation"] = np.clip(np.round(128 * q[order] + 128), 0, 255)
    Path(path).write_bytes(rec.tobytes())


def read_splat(path: str | Path) -> tuple[dict, int]:
    """(Gaussians in the capture's coordinates, SH degree 0) of a .splat file."""
    raw = Path(path).read_bytes()
    if len(raw) == 0 or len(raw) % RECORD.itemsize:
        raise ValueError(f"{len(raw)} bytes is not a whole number of {RECORD.itemsize}-byte records (truncated?)")
    rec = np.frombuffer(raw, RECORD)
    n = len(rec)
    scale = rec["scale"].astype(np.float64)
    if not (scale > 0).all():
        raise ValueError(f"{int((~(scale > 0)).sum())} records have a scale that is not positive")
    rgba = rec["rgba"].astype(np.float64) / 255
    alpha = np.clip(rgba[:, 3], _ALPHA_EPS, 1 - _ALPHA_EPS)
    g = {"means": rec["position"].astype(np.float32), "log_scales": np.log(scale).astype(np.float32),
         "quats": ((rec["rotation"].astype(np.float32) - 128) / 128),
         "opacity": (np.log(alpha) - np.log1p(-alpha)).astype(np.float32),
         "sh_dc": ((rgba[:, :3] - 0.5) / SH_C0).astype(np.float32).reshape(n, 1, 3),
         "sh_rest": np.zeros((n, N_REST, 3), np.float32)}
    return g, 0


FORMAT = SplatFormat(name="antimatter15 .splat", opens="antimatter15/splat, Spark, GaussianSplats3D, SuperSplat",
                     max_sh=0, write=write_splat, read=read_splat)
