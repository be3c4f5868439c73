"""Multiresolution hash encoding (Mueller et al. 2022, "Instant Neural Graphics
Primitives with a Multiresolution Hash Encoding").

A point x in [0, 1]^3 is encoded by L grids of increasing resolution N_0 < ... < N_{L-1}.
At level l the point is scaled to p = x * N_l, which lies in the cell with integer lower
corner c = floor(p) (clamped to [0, N_l - 1], so x = 1 uses the last cell) and local
coordinate f = p - c in [0, 1]^3. The level feature is the trilinear blend of the
F-dimensional feature vectors stored for the 8 corners c + o, o in {0, 1}^3:

    enc_l(x) = sum_o  w_o(f) * theta_l[ index_l(c + o) ],
    w_o(f)   = prod_d ( f_d if o_d == 1 else 1 - f_d ).

A level has (N_l + 1)^3 vertices. When (N_l + 1)^3 <= T = 2^log2_table_size the level is
*dense*: vertex (i, j, k) owns row  i + j * (N_l + 1) + k * (N_l + 1)^2  of a table with
exactly (N_l + 1)^3 rows (smaller than T, saving memory). Otherwise the level is *hashed*
into a table of T rows with the paper's spatial hash (uint32 arithmetic, mod 2^32):

    index_l(i, j, k) = ( (i * 1) xor (j * 2654435761) xor (k * 805459861) ) mod T.

Parameters are a plain pytree {"tables": [theta_0, ..., theta_{L-1}]}, theta_l float32
[rows_l, F]. Each level is looked up in its own table, one gather of [N] rows per cell
corner (_level_corners). This was
measured against a single gather over all levels from one concatenated table (static
per-level row offsets) on a 2-core CPU, 2^18 points, default config: the per-level form
is ~2-3x faster for forward+backward (~0.3-0.6 s vs ~1.0-1.6 s), because the per-level
gathers/scatter-adds touch one small table at a time (cache-friendly) while XLA:CPU's
batched [N, L, 8] gather and its scatter-add transpose are slow, and a concatenated table
sliced per level makes autodiff materialise L full-size zero gradients. See
benchmarks/hashgrid_speed.py (--compare) to re-measure.

The dense levels (each its own table size) are a Python loop; the hashed levels, whose tables
all have T rows, are one `lax.scan` over their stacked tables (the level is the scanned axis,
so each iteration still gathers from one table and autodiff hands back one [T, F] gradient per
level). The same arithmetic, so the same output bit for bit, and the same speed (ngp preset,
2^16 points, forward + backward: 90 ms either way on 2 cores), but XLA compiles the level's
gathers and their scatter-add transposes once instead of once per level: the encoding's
forward + backward compiles in 2.8 s instead of 5.7 s, and an ngp training step (16 levels,
11 hashed) in about half a second less per level.

The output concatenates the levels, coarsest first: [N, L * F] with
out[:, l * F:(l + 1) * F] = enc_l(x).

Everything is float32 and static-shaped; `HashGridConfig` is a frozen (hashable)
dataclass, so it can be a static argument of jax.jit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

# Per-axis primes of the spatial hash (Teschner et al. 2003, as used by Instant-NGP).
HASH_PRIMES = (1, 2654435761, 805459861)

# The 8 corner offsets o in {0,1}^3, corner b has o = (b & 1, (b >> 1) & 1, (b >> 2) & 1).
CORNER_OFFSETS = np.array([[(b >> d) & 1 for d in range(3)] for b in range(8)], dtype=np.int32)


@dataclass(frozen=True)
class HashGridConfig:
    """Static configuration of a multiresolution hash grid.

    Attributes:
      n_levels: L, the number of levels.
      features_per_level: F, feature channels stored per vertex.
      log2_table_size: log2 of T, the maximum number of rows of one level's table.
      base_resolution: N_0, the resolution (cells per axis) of the coarsest level.
      finest_resolution: N_{L-1}, the resolution of the finest level.
    """

    n_levels: int = 16
    features_per_level: int = 2
    log2_table_size: int = 19
    base_resolution: int = 16
    finest_resolution: int = 2048  # resolution of the finest level

    @property
    def table_size(self) -> int:
        """T = 2^log2_table_size."""
        return 1 << self.log2_table_size

    @property
    def output_dim(self) -> int:
        """L * F, the width of the encoding."""
        return self.n_levels * self.features_per_level


def level_resolutions(cfg: HashGridConfig) -> list[int]:
    """Per-level grid resolutions N_l (cells per axis), coarsest first.

        b   = exp( (ln N_max - ln N_min) / (L - 1) ),
        N_l = floor( N_min * b^l ),   l = 0 .. L-1.

    Evaluated in float64 and floored with a 1e-9 relative tolerance so that round-off
    never turns N_{L-1} = N_max into N_max - 1. With L == 1 the single level is N_min.

    Returns:
      A list of L Python ints.
    """
    n_min, n_max, n_lv = cfg.base_resolution, cfg.finest_resolution, cfg.n_levels
    if n_lv == 1:
        return [int(n_min)]
    b = math.exp((math.log(n_max) - math.log(n_min)) / (n_lv - 1))
    return [int(math.floor(n_min * b**lvl * (1.0 + 1e-9))) for lvl in range(n_lv)]


def level_is_dense(cfg: HashGridConfig) -> list[bool]:
    """Whether each level is directly indexed: (N_l + 1)^3 <= T."""
    return [(r + 1) ** 3 <= cfg.table_size for r in level_resolutions(cfg)]


def level_table_sizes(cfg: HashGridConfig) -> list[int]:
    """Rows of each level's table: (N_l + 1)^3 if dense, else T."""
    return [min((r + 1) ** 3, cfg.table_size) for r in level_resolutions(cfg)]


def init_hashgrid(key: jax.Array, cfg: HashGridConfig) -> dict:
    """Initialises all feature tables ~ Uniform(-1e-4, 1e-4), as in the paper.

    Returns:
      {"tables": [float32 [level_table_sizes(cfg)[l], F] for l in range(L)]}.
    """
    keys = jax.random.split(key, cfg.n_levels)
    return {
        "tables": [
            jax.random.uniform(k, (rows, cfg.features_per_level), jnp.float32, -1e-4, 1e-4)
            for k, rows in zip(keys, level_table_sizes(cfg))
        ]
    }


def _level_corners(x: jax.Array, resolution: int, dense: bool, table_size: int):
    """Table rows and trilinear weights of the 8 cell corners of x at one level.

    Args:
      x: float32 [N, 3], already clipped to [0, 1]^3.
      resolution: N_l (static when dense; a float32 scalar may stand for it in a hashed level).
      dense: whether the level is directly indexed (static).
      table_size: T, a power of two (static), so `mod T` is `& (T - 1)`.

    Returns:
      A list of 8 pairs (idx int32 [N], w float32 [N]), one per corner o (ordered as CORNER_OFFSETS):
      the row of c + o in [0, rows_l) and w_o(f) = prod_d (f_d if o_d else 1 - f_d) (the 8 sum to 1).
      Kept as 8 separate arrays: stacking them into [N, 8] makes XLA:CPU emit a concatenate fusion that
      cost more than the gathers (measured on lego, 2 cores: encoding 2^15 points 10.2 ms stacked vs
      5.0 ms as 8 gathers of [N] rows; forward + backward of 2^16 points 75 vs 70 ms).
    """
    res = jnp.float32(resolution)  # a Python int, or a traced scalar for a scanned hashed level
    pos = x * res  # [N, 3]
    cell = jnp.clip(jnp.floor(pos), 0.0, res - 1.0)
    frac = pos - cell  # [N, 3], in [0, 1]
    c = cell.astype(jnp.uint32)
    # Per-axis index terms c_d * m_d and (c_d + 1) * m_d (uint32, wrapping); the row of
    # corner o combines one term per axis with + (dense) or xor (hashed).
    mults = (1, resolution + 1, (resolution + 1) ** 2) if dense else HASH_PRIMES
    terms = [(c[:, d] * jnp.uint32(m), (c[:, d] + 1) * jnp.uint32(m)) for d, m in enumerate(mults)]
    combine = jnp.add if dense else jnp.bitwise_xor
    one_minus = 1.0 - frac
    corners = []
    for ox, oy, oz in CORNER_OFFSETS:
        i = combine(combine(terms[0][ox], terms[1][oy]), terms[2][oz])
        if not dense:
            i = i & jnp.uint32(table_size - 1)
        wx = frac[:, 0] if ox else one_minus[:, 0]
        wy = frac[:, 1] if oy else one_minus[:, 1]
        wz = frac[:, 2] if oz else one_minus[:, 2]
        corners.append((i.astype(jnp.int32), wx * wy * wz))
    return corners


def hashgrid_indices(x: jax.Array, cfg: HashGridConfig):
    """Table rows and trilinear weights used to encode x at every level.

    Args:
      x: float32 [N, 3] points in [0, 1]^3 (values outside are clipped).
      cfg: the grid configuration.

    Returns:
      idx: int32 [N, L, 8], row of corner o of level l in params["tables"][l],
        in [0, level_table_sizes(cfg)[l]).
      weights: float32 [N, L, 8], trilinear weights w_o(f); sum to 1 over corners.
    """
    x = jnp.clip(jnp.asarray(x, jnp.float32), 0.0, 1.0)
    out = [_level_corners(x, r, d, cfg.table_size) for r, d in zip(level_resolutions(cfg), level_is_dense(cfg))]
    idx = jnp.stack([jnp.stack([i for i, _ in lv], axis=-1) for lv in out], axis=1)
    return idx, jnp.stack([jnp.stack([w for _, w in lv], axis=-1) for lv in out], axis=1)


def level_weights(scale: jax.Array, cfg: HashGridConfig) -> jax.Array:
    """Anti-aliasing weights [N, L] of the levels for Gaussian footprints of std `scale` [N] (in units of
    the unit cube the grid covers), after Zip-NeRF's feature downweighting (Barron et al. 2023, eq. 6):

        omega_l = erf(1 / sqrt(8 scale^2 N_l^2)) = P(|z| < h_l / 2),  z ~ N(0, scale^2),  h_l = 1 / N_l

    the chance that a point of the footprint falls within half a cell of level l of its centre: ~1 for
    levels coarser than the footprint, -> 0 for levels much finer (their features would alias).
    scale = 0 gives 1 for every level (the plain encoding)."""
    res = jnp.asarray(level_resolutions(cfg), jnp.float32)  # [L]
    s = jnp.maximum(jnp.asarray(scale, jnp.float32), 1e-12)[:, None]
    return jax.scipy.special.erf(1.0 / (jnp.sqrt(8.0) * s * res[None, :]))


def encode_hashgrid(params: dict, x: jax.Array, cfg: HashGridConfig, scale: jax.Array | None = None) -> jax.Array:
    """Multiresolution hash encoding of points x in [0, 1]^3.

        enc(x) = concat_l  sum_o w_o(f_l) * tables[l][ index_l(c_l + o) ]  (see module doc)

    Gradients w.r.t. the tables are the scatter-adds jax derives from the gathers;
    gradients w.r.t. x flow through the trilinear weights (zero where x was clipped).

    Args:
      params: {"tables": [float32 [rows_l, F]] * L} from `init_hashgrid`.
      x: float32 [N, 3] points in [0, 1]^3; values outside are clipped to the cube.
      cfg: the grid configuration (static under jit).
      scale: optional float32 [N], the std of each point's footprint in cube units: level l's
        features are multiplied by level_weights(scale)[:, l] (anti-aliasing); None: weight 1.

    Returns:
      float32 [N, L * F], level-major (level l occupies columns l*F .. (l+1)*F - 1).
    """
    tables = params["tables"]
    if len(tables) != cfg.n_levels:
        raise ValueError(f"params has {len(tables)} level tables, cfg.n_levels={cfg.n_levels}")
    x = jnp.clip(jnp.asarray(x, jnp.float32), 0.0, 1.0)
    resolutions, dense = level_resolutions(cfg), level_is_dense(cfg)
    n_dense = sum(dense)
    assert not any(dense[n_dense:]), "resolutions grow with the level, so the dense levels come first"

    def level(table, resolution, is_dense):
        # One gather of [N, F] rows per corner, weighted and summed (XLA fuses the sum into one loop).
        return sum(w[:, None] * table.at[i].get(mode="promise_in_bounds")
                   for i, w in _level_corners(x, resolution, is_dense, cfg.table_size))

    outs = [level(t, r, True) for t, r in zip(tables[:n_dense], resolutions[:n_dense])]
    if n_dense < cfg.n_levels:  # the hashed levels: one scan over [L - n_dense, T, F]
        _, hashed = jax.lax.scan(lambda _, lv: (None, level(lv[0], lv[1], False)), None,
                                 (jnp.stack(tables[n_dense:]), jnp.asarray(resolutions[n_dense:], jnp.float32)))
        outs.append(jnp.transpose(hashed, (1, 0, 2)).reshape(x.shape[0], -1))  # [N, (L - n_dense) F], level-major
    out = jnp.concatenate(outs, axis=-1)
    if scale is not None:
        omega = level_weights(scale, cfg)  # [N, L]
        out = (out.reshape(x.shape[0], cfg.n_levels, -1) * omega[:, :, None]).reshape(x.shape[0], -1)
    return out
