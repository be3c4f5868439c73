"""The scene box as a grid, and the trained field as jitted functions of points (for the exports).

The grid of resolution N over [-B, B]^3 has the points x_ijk = -B + (i, j, k) h, h = 2B / (N - 1),
visited in slabs of x-slices and fixed-size chunks so memory stays bounded and each function
compiles once.
"""

from __future__ import annotations

import jax
import numpy as np

from nerfkit.run.folder import TrainedRun

CHUNK = 65536


def grid_axis(bound: float, resolution: int) -> np.ndarray:
    """The N sample coordinates -B + i h, i = 0..N-1, of each axis (float32 [N])."""
    return np.linspace(-bound, bound, resolution, dtype=np.float32)


def chunked(fn, *arrays: np.ndarray, chunk: int = CHUNK) -> np.ndarray:
    """fn applied to rows of arrays [M, ...] in fixed-size chunks (the last one padded, so fn
    compiles once); returns the concatenated numpy result [M, ...]."""
    m = len(arrays[0])
    outs = []
    for s in range(0, m, chunk):
        part = [a[s:s + chunk] for a in arrays]
        n = len(part[0])
        if n < chunk:
            part = [np.concatenate([p, np.zeros((chunk - n, *p.shape[1:]), p.dtype)]) for p in part]
        outs.append(np.asarray(fn(*part))[:n])
    return np.concatenate(outs) if outs else np.zeros((0,), np.float32)


def slab_points(axis: np.ndarray, i0: int, i1: int) -> np.ndarray:
    """Grid points [(i1 - i0) N^2, 3] of x-slices i0..i1-1, in C order (i, j, k)."""
    gx, gy, gz = np.meshgrid(axis[i0:i1], axis, axis, indexing="ij")
    return np.stack([gx, gy, gz], axis=-1).reshape(-1, 3)


def field_functions(run: TrainedRun):
    """(density_fn, color_fn, occupied_fn or None, occupancy cell size) of a trained model,
    jitted, in the normalised frame. color_fn(x, d) is the field's colour at x seen along unit d
    (held-out appearance: the mean embedding)."""
    field, p, occupied, cell = run.model.surface_field(run.params, run.aux)
    occupied_fn = None if occupied is None else jax.jit(occupied)
    emb = field.embedding(p, None)
    density_fn = jax.jit(lambda x: field.density(p, x))
    color_fn = jax.jit(lambda x, d: field(p, x, d, emb)[0])
    return density_fn, color_fn, occupied_fn, cell
