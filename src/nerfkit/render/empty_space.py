"""Empty-space skipping for occupancy-marched rays: candidate sets as bit masks (pack_bits, first_set_bits),
the chessboard distance from each grid cell to the nearest occupied one (empty_distance), and sphere tracing
over it along a ray's own march (skip_empty). The wavefront renderer (wavefront.py) is built on these."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.sampling import occupancy


def first_set_bits(words: jnp.ndarray, k: int):
    """Positions of the k lowest set bits of each row of a bit mask, and of the next one.

    words: uint32 [R, M], bit b of words[:, m] is candidate 32 m + b. Returns pos int32
    [R, k] (ascending; valid only where ok), ok bool [R, k] (a prefix of each row: True for
    the first min(popcount, k) entries), and rest int32 [R] (the position of the (k+1)-th
    set bit, -1 when there is none). The lowest set bit of a word v is v & -v, its position
    popcount((v & -v) - 1); clearing it is v & (v - 1).
    """
    rows = jnp.arange(words.shape[0])

    def lowest(w):
        m = jnp.argmax(w != 0, axis=1)  # first non-zero word (0 when all are zero)
        v = w[rows, m]
        low = v & (~v + jnp.uint32(1))
        pos = 32 * m.astype(jnp.int32) + jax.lax.population_count(low - jnp.uint32(1)).astype(jnp.int32)
        return pos, v != 0, w.at[rows, m].set(v & (v - jnp.uint32(1)))

    pos, ok = [], []
    for _ in range(k):
        p, o, words = lowest(words)
        pos.append(p)
        ok.append(o)
    p, o, _ = lowest(words)
    return jnp.stack(pos, axis=1), jnp.stack(ok, axis=1), jnp.where(o, p, -1)


def pack_bits(keep: jnp.ndarray) -> jnp.ndarray:
    """bool [R, 32 M] -> uint32 [R, M] with bit b of word m set where keep[:, 32 m + b]."""
    r, w = keep.shape
    shifts = jnp.arange(32, dtype=jnp.uint32)
    return jnp.sum(keep.reshape(r, w // 32, 32).astype(jnp.uint32) << shifts, axis=-1, dtype=jnp.uint32)


def empty_distance(bits: np.ndarray, resolution: int) -> np.ndarray:
    """Chessboard distance D [R^3] (int32, flat like the occupancy bits) from each cell to the nearest
    occupied cell, in cells: 0 at occupied cells, 1 next to one, ...; R everywhere when none is occupied.
    Every cell c' with |c' - c|_inf <= D(c) - 1 is then unoccupied."""
    from scipy import (
        ndimage,  # imported here: it costs 0.13 s of every command's start-up
    )

    occ = np.asarray(bits, bool).reshape((resolution,) * 3)
    if not occ.any():
        return np.full(occ.size, resolution, np.int32)
    return ndimage.distance_transform_cdt(~occ, metric="chessboard").astype(np.int32).reshape(-1)


def skip_empty(candidates, to_grid, occ_cfg, dist, lipschitz: float, o, d, k, iters: int = 3, search_bits: int = 10):
    """Advance candidate indices k [R] past candidates whose midpoints certainly lie in unoccupied cells.

    A midpoint x whose grid point y = to_grid(x) is in a cell at chessboard distance D >= 1 from every
    occupied cell has a clearance of (D - 1) h (h the cell size): every grid point within that L-inf
    (so also L2) distance of y is in an unoccupied cell. to_grid is `lipschitz`-Lipschitz (1 for the box,
    1 / radius for the contraction, which never stretches), so every point of the ray with
    |t' - t| |d| lipschitz <= (D - 1) h is unoccupied too: candidate k and the following n ones, n the
    largest with t_mid(k + n) <= t_mid(k) + (D - 1) h / (|d| lipschitz) (binary search over
    n < 2^search_bits, on `candidates`' own t grid, so the same samples are kept as without the skip),
    are skipped: k <- k + n + 1. Repeated `iters` times (sphere tracing over the distance field).

    candidates(o, d, None, index [R, 1]) -> t_start, t_end, cand [R, 1] (the model's march);
    dist: int32 [R^3] (empty_distance). Returns int32 [R]."""
    h = occ_cfg.cell_size
    norm = jnp.linalg.norm(d, axis=-1)

    def mid(kk):
        t0, t1, cand = candidates(o, d, None, kk[:, None])
        return 0.5 * (t0 + t1)[:, 0], cand[:, 0]

    for _ in range(iters):
        t, cand = mid(k)
        idx, inside = occupancy.world_to_cell(to_grid(o + t[:, None] * d), occ_cfg)
        gap = dist[idx]
        reach = t + 0.999 * (gap.astype(jnp.float32) - 1.0) * h / jnp.maximum(norm * lipschitz, 1e-12)
        n = jnp.zeros_like(k)
        for b in reversed(range(search_bits)):
            trial = n + (1 << b)
            tm, c = mid(k + trial)
            n = jnp.where(c & (tm <= reach), trial, n)
        k = jnp.where(cand & inside & (gap >= 1), k + n + 1, k)
    return k
