"""Occupancy grid for empty-space skipping, a packed ray marcher and packed rendering.

Grid. The box [-B, B]^3 (B = cfg.bound) is split into R^3 cubic cells of side
h = 2B / R (R = cfg.resolution). Cell (i, j, k) covers
[-B + i h, -B + (i + 1) h] x [..j..] x [..k..], has centre -B + (i + 1/2, j + 1/2, k + 1/2) h,
and flat index  c = (i * R + j) * R + k  (C order of an [R, R, R] array indexed [x, y, z]).

State (a plain pytree dict):
    "density":   float32 [R^3]  running estimate rho_c of the max density sigma in cell c.
    "bits":      bool    [R^3]  occupancy, bits_c = rho_c > min(threshold, mean_c rho_c).
    "n_updates": int32   []     number of `update_occupancy` calls so far.

Update (instant-ngp's schedule, Mueller et al. 2022, Sec. 4 / Appendix E.2):
    * one density evaluation per selected cell at a uniformly jittered point inside it;
    * selection: every cell during warm-up (step < warmup_steps) and at the very first update;
      afterwards R^3/4 cells drawn uniformly plus R^3/4 cells drawn uniformly among the
      currently occupied ones (both with replacement);
    * new_c = max of the sigmas evaluated in cell c this update (0 if none);
    * rho_c <- new_c at the first update (it replaces the "everything occupied" initial
      value), afterwards rho_c <- max(decay * rho_c, new_c), decay = ema_decay (0.95), or
      warmup_decay during the warm-up's full passes (nerfkit's ngp preset: 0.6, so that a
      CPU run of a few hundred steps already skips empty space);
    * bits_c = rho_c > min(threshold, mean(rho)).
  `threshold` is in units of density sigma (1/length). instant-ngp stores optical thickness
  sigma * dt_min instead, with threshold 0.01; 0.01 in sigma units is more conservative
  (keeps more cells). The min(., mean) makes a young, uniformly low-density field keep
  roughly its above-average cells instead of none; a field whose density is exactly 0
  everywhere would mark nothing occupied, so use a strictly positive density activation
  (exp / softplus / trunc_exp) as instant-ngp does.
  The caller decides how often to update (instant-ngp: every 16 training steps).

Ray marching produces a packed, statically-shaped list of samples whose interval
midpoints lie in occupied cells; packed_weights / packed_composite render them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from nerfkit.rays.coord import spacing, spacing_inverse

INIT_DENSITY = 1e4  # initial rho: large, so every cell starts occupied.


@dataclass(frozen=True)
class OccupancyConfig:
    """Static configuration of the occupancy grid.

    Attributes:
      resolution: R, cells per axis.
      bound: B, the grid covers the axis-aligned box [-B, B]^3.
      ema_decay: decay of the running max, rho <- max(decay * rho, new).
      warmup_decay: the decay during warm-up (full passes), when the young field changes fast
        (None: ema_decay).
      threshold: a cell is occupied when rho > min(threshold, mean(rho)); sigma units.
    """

    resolution: int = 128
    bound: float = 1.5
    ema_decay: float = 0.95
    warmup_decay: float | None = None
    threshold: float = 0.01

    @property
    def n_cells(self) -> int:
        return self.resolution**3

    @property
    def cell_size(self) -> float:
        """h = 2B / R."""
        return 2.0 * self.bound / self.resolution


def init_occupancy(cfg: OccupancyConfig) -> dict:
    """All cells occupied: rho = INIT_DENSITY, bits = True, n_updates = 0.

    Returns:
      {"density": float32 [R^3], "bits": bool [R^3], "n_updates": int32 []}.
    """
    return {
        "density": jnp.full((cfg.n_cells,), INIT_DENSITY, jnp.float32),
        "bits": jnp.ones((cfg.n_cells,), bool),
        "n_updates": jnp.zeros((), jnp.int32),
    }


def cell_coords(cell_idx: jax.Array, cfg: OccupancyConfig) -> jax.Array:
    """Flat cell index c -> integer coordinates (i, j, k), c = (i R + j) R + k.

    Args:
      cell_idx: int [...].
    Returns:
      int32 [..., 3].
    """
    r = cfg.resolution
    c = jnp.asarray(cell_idx, jnp.int32)
    return jnp.stack([c // (r * r), (c // r) % r, c % r], axis=-1)



def world_to_cell(x: jax.Array, cfg: OccupancyConfig):
    """Cell containing each point.

    i_d = clip(floor((x_d + B) / h), 0, R - 1); a point is inside when all |x_d| <= B.

    Args:
      x: float [N, 3] world positions.
    Returns:
      cell_idx: int32 [N], flat index of the (clamped) cell.
      inside: bool [N], whether x lies in the closed box [-B, B]^3 (False for NaN).
    """
    x = jnp.asarray(x, jnp.float32)
    r = cfg.resolution
    ijk = jnp.floor((x + cfg.bound) * jnp.float32(r / (2.0 * cfg.bound)))
    ijk = jnp.clip(ijk, 0, r - 1).astype(jnp.int32)
    inside = jnp.all(jnp.abs(x) <= cfg.bound, axis=-1)
    return (ijk[..., 0] * r + ijk[..., 1]) * r + ijk[..., 2], inside


def query_occupancy(state: dict, x: jax.Array, cfg: OccupancyConfig) -> jax.Array:
    """Whether each point lies in an occupied cell; points outside the box are unoccupied.

    Args:
      state: occupancy state from `init_occupancy` / `update_occupancy`.
      x: float [N, 3] world positions.
    Returns:
      bool [N].
    """
    idx, inside = world_to_cell(x, cfg)
    return state["bits"][idx] & inside


def _eval_chunked(density_fn: Callable, pts: jax.Array, chunk_size: int) -> jax.Array:
    """density_fn over [M, 3] points in static chunks of `chunk_size` (lax.map). -> [M]."""
    m = pts.shape[0]
    if m <= chunk_size:
        return jnp.reshape(density_fn(pts), (m,)).astype(jnp.float32)
    n_chunks = -(-m // chunk_size)
    padded = jnp.pad(pts, ((0, n_chunks * chunk_size - m), (0, 0)))
    out = jax.lax.map(
        lambda p: jnp.reshape(density_fn(p), (chunk_size,)).astype(jnp.float32),
        padded.reshape(n_chunks, chunk_size, 3),
    )
    return out.reshape(-1)[:m]


def _max_density_at_cells(cells, key, density_fn, cfg, chunk_size):
    """new_c = max over selected entries of sigma(jittered point in c), 0 for unselected.

    Args:
      cells: int32 [M] flat cell indices (repeats allowed).
    Returns:
      float32 [R^3].
    """
    u = jax.random.uniform(key, (cells.shape[0], 3), jnp.float32)
    pts = -cfg.bound + (cell_coords(cells, cfg).astype(jnp.float32) + u) * cfg.cell_size
    sigma = _eval_chunked(density_fn, pts, chunk_size)
    return jnp.zeros((cfg.n_cells,), jnp.float32).at[cells].max(sigma)


def update_occupancy(
    state: dict,
    density_fn: Callable[[jax.Array], jax.Array],
    key: jax.Array,
    step,
    cfg: OccupancyConfig,
    warmup_steps: int = 256,
    chunk_size: int = 1 << 16,
) -> dict:
    """One occupancy-grid update (see module docstring for the exact rule).

    Args:
      state: current state.
      density_fn: sigma(x), float [M, 3] -> float [M] (>= 0). Called on chunks of at most
        `chunk_size` points (static size) inside lax.map; wrap parameters in a closure.
      key: PRNG key for jitter and cell selection.
      step: training step (int or traced int32 scalar). step < warmup_steps evaluates
        every cell; later steps evaluate R^3/4 uniform + R^3/4 occupied cells.
      cfg: grid configuration (static).
      warmup_steps: static int.
      chunk_size: static int, points per density_fn call.
    Returns:
      The new state (same structure).
    """
    n = cfg.n_cells
    k_full, k_unif, k_occ, k_jit = jax.random.split(key, 4)
    full_pass = (jnp.asarray(step) < warmup_steps) | (state["n_updates"] == 0)

    def all_cells(_):
        cells = jnp.arange(n, dtype=jnp.int32)
        return _max_density_at_cells(cells, k_full, density_fn, cfg, chunk_size)

    def subset(_):
        m = max(n // 4, 1)
        unif = jax.random.randint(k_unif, (m,), 0, n, dtype=jnp.int32)
        # Uniform draw among occupied cells: inverse CDF of the 0/1 occupancy mass.
        csum = jnp.cumsum(state["bits"].astype(jnp.int32))
        n_occ = csum[-1]
        r = jax.random.randint(k_occ, (m,), 0, jnp.maximum(n_occ, 1), dtype=jnp.int32)
        occ = jnp.searchsorted(csum, r, side="right").astype(jnp.int32)
        occ = jnp.where(n_occ > 0, occ, unif)
        cells = jnp.concatenate([unif, occ])
        return _max_density_at_cells(cells, k_jit, density_fn, cfg, chunk_size)

    new = jax.lax.cond(full_pass, all_cells, subset, None)
    warm = cfg.ema_decay if cfg.warmup_decay is None else cfg.warmup_decay
    decay = jnp.where(full_pass, jnp.float32(warm), jnp.float32(cfg.ema_decay))
    decayed = jnp.maximum(state["density"] * decay, new)
    density = jnp.where(state["n_updates"] == 0, new, decayed)
    thresh = jnp.minimum(jnp.float32(cfg.threshold), jnp.mean(density))
    return {
        "density": density,
        "bits": density > thresh,
        "n_updates": state["n_updates"] + 1,
    }


def ray_box_intersect(origins: jax.Array, directions: jax.Array, bound: float):
    """Slab-method intersection of rays o + t d with the box [-B, B]^3.

    Args:
      origins, directions: float [R, 3] (d need not be unit; t is in units of d).
    Returns:
      t_enter, t_exit: float32 [R]; the ray is inside the box for t in [t_enter, t_exit]
      and misses it when t_exit < t_enter. Zero direction components are replaced by
      +-1e-12 (keeping the sign) so the slabs stay finite.
    """
    o = jnp.asarray(origins, jnp.float32)
    d = jnp.asarray(directions, jnp.float32)
    d = jnp.where(jnp.abs(d) < 1e-12, jnp.where(d < 0, -1e-12, 1e-12), d)
    t0 = (-bound - o) / d
    t1 = (bound - o) / d
    t_enter = jnp.max(jnp.minimum(t0, t1), axis=-1)
    t_exit = jnp.min(jnp.maximum(t0, t1), axis=-1)
    return t_enter, t_exit


def default_max_steps(cfg: OccupancyConfig, step_size: float) -> int:
    """K = ceil(2 sqrt(3) B / step_size): candidates needed to cross the box diagonal with
    unit-length directions."""
    return max(1, int(math.ceil(2.0 * math.sqrt(3.0) * cfg.bound / step_size)))


def march_rays(
    state: dict,
    origins: jax.Array,
    directions: jax.Array,
    near,
    far,
    cfg: OccupancyConfig,
    step_size: float,
    max_samples: int,
    key: jax.Array | None = None,
    max_steps: int | None = None,
) -> dict:
    """Packed samples along rays, skipping unoccupied cells.

    For ray r with [t_lo, t_hi] = [max(near, t_enter), min(far, t_exit)], jitter
    j_r ~ U[0, 1) (j_r = 0 when key is None) and k = 0 .. K-1 the candidate intervals are

        t_start_k = t_lo + (k + j_r) * step_size,   t_end_k = min(t_start_k + step_size, t_hi),

    and candidate k is kept iff t_start_k < t_hi and the midpoint
    o + (t_start_k + t_end_k) / 2 * d lies in an occupied cell. Kept candidates of all
    rays are compacted (flattened [R, K] in ray-major order, so sorted by ray then t) into
    the first entries of `max_samples` slots.

    Static shapes / memory: candidates are processed as [R, K] arrays (about 40 bytes per
    candidate: t_start, t_end, midpoint, position, cell index, masks; ~170 MB at R=4096,
    K=1024; measured ~0.2 s on 2 CPU cores at R^3 = 128^3). K = max_steps, default `default_max_steps(cfg, step_size)`,
    which covers the box diagonal for unit directions; with |d| < 1 pass a larger
    max_steps, otherwise rays are truncated after K steps.
    Overflow: if more than max_samples candidates are kept, the first max_samples in
    ray-major order are returned (rays at the end of the batch lose samples);
    compare n_candidates with max_samples to detect it.

    Args:
      state: occupancy state.
      origins, directions: float [R, 3]; t is measured in units of |d|.
      near, far: scalars or float [R].
      cfg: occupancy configuration (static).
      step_size: static float, interval length in t units.
      max_samples: static int, S, size of the packed output.
      key: optional PRNG key for the per-ray jitter.
      max_steps: optional static int K.

    Returns dict with
      "ray_idx": int32 [S], ray of each sample (invalid slots: R - 1, so ray_idx is
        non-decreasing over all slots);
      "t_start", "t_end": float32 [S], the sample interval (invalid slots: a zero-length
        interval at t_hi of the last ray, so they carry no optical depth);
      "valid": bool [S], True for the first n_valid slots;
      "n_valid": int32 [], min(n_candidates, S);
      "n_candidates": int32 [], number of kept candidates before truncation to S;
      "ray_counts": int32 [R], kept candidates per ray;
      "complete": bool [R], True for rays all of whose samples fit in the S slots.
    """
    o = jnp.asarray(origins, jnp.float32)
    d = jnp.asarray(directions, jnp.float32)
    k_steps = default_max_steps(cfg, step_size) if max_steps is None else int(max_steps)
    t_start, t_end, cand = box_candidates(o, d, near, far, cfg.bound, step_size, k_steps, key)
    return pack_candidates(state, o, d, t_start, t_end, cand, cfg, max_samples)


def _jitter(key, n_rays: int):
    return jnp.zeros((n_rays,), jnp.float32) if key is None else jax.random.uniform(key, (n_rays,), jnp.float32)


def box_candidates(o, d, near, far, bound: float, step_size: float, k_steps: int, key=None, index=None):
    """Candidate intervals at a fixed step inside the box [-B, B]^3 (see march_rays).

    Candidate k of ray r starts at t_lo + (k + j_r) step. By default k = 0 .. k_steps - 1
    for every ray ([R, K] outputs); `index` (int [R, W]) asks for other candidates of each
    ray, as the wavefront renderer does. Returns t_start, t_end (float32) and cand (bool:
    the interval starts before the ray leaves the box or passes far), shaped like index.
    """
    n_rays = o.shape[0]
    t_enter, t_exit = ray_box_intersect(o, d, bound)
    t_lo = jnp.maximum(jnp.broadcast_to(jnp.asarray(near, jnp.float32), (n_rays,)), t_enter)
    t_hi = jnp.minimum(jnp.broadcast_to(jnp.asarray(far, jnp.float32), (n_rays,)), t_exit)
    k = jnp.arange(k_steps, dtype=jnp.float32)[None, :] if index is None else index.astype(jnp.float32)
    t_start = t_lo[:, None] + (k + _jitter(key, n_rays)[:, None]) * jnp.float32(step_size)
    t_end = jnp.minimum(t_start + jnp.float32(step_size), t_hi[:, None])
    return t_start, t_end, t_start < t_hi[:, None]


def contracted_candidates(n_rays: int, near, far, radius: float, k_steps: int, key=None, index=None):
    """Candidate intervals evenly spaced in s = coord.spacing(t, radius) over [g(near), g(far)]:
    evenly in t up to t = radius, evenly in disparity beyond.

    With jitter j_r (0 without key) and ds = (g(far) - g(near)) / K, candidate k spans
    s in [g(near) + (k + j_r) ds, g(near) + (k + 1 + j_r) ds] clipped to g(far), mapped
    back to t; k = 0 .. K - 1, or the candidates `index` (int [R, W]) of each ray. Returns
    t_start, t_end (float32) and cand (bool), [R, K] or shaped like index.
    """
    s_lo = spacing(jnp.float32(near), radius)
    s_hi = spacing(jnp.float32(far), radius)
    ds = (s_hi - s_lo) / k_steps
    k = jnp.arange(k_steps, dtype=jnp.float32)[None, :] if index is None else index.astype(jnp.float32)
    s0 = s_lo + (k + _jitter(key, n_rays)[:, None]) * ds
    s1 = jnp.minimum(s0 + ds, s_hi)
    cand = s0 < s_hi
    return spacing_inverse(jnp.minimum(s0, s_hi), radius), spacing_inverse(s1, radius), cand


def pack_candidates(state: dict, o, d, t_start, t_end, cand, cfg: OccupancyConfig, max_samples: int,
                    to_grid=None) -> dict:
    """Keep the candidates whose midpoint lies in an occupied cell and pack them (see march_rays).

    to_grid maps world points [M, 3] to grid coordinates (identity for bounded fields,
    the contraction for unbounded ones).
    """
    n_rays, k_steps = t_start.shape
    t_mid = 0.5 * (t_start + t_end)
    pts = (o[:, None, :] + t_mid[..., None] * d[:, None, :]).reshape(-1, 3)  # [R K, 3]
    if to_grid is not None:
        pts = to_grid(pts)
    keep = cand & query_occupancy(state, pts, cfg).reshape(n_rays, k_steps)

    counts = jnp.sum(keep, axis=1, dtype=jnp.int32)
    flat_keep = keep.reshape(-1)
    n_cand = jnp.sum(counts)
    (sel,) = jnp.nonzero(flat_keep, size=max_samples, fill_value=0)
    valid = jnp.arange(max_samples, dtype=jnp.int32) < n_cand
    t_pad = jnp.max(jnp.where(cand[n_rays - 1], t_end[n_rays - 1], t_start[n_rays - 1, 0]))
    return {
        "ray_idx": jnp.where(valid, sel // k_steps, n_rays - 1).astype(jnp.int32),
        "t_start": jnp.where(valid, t_start.reshape(-1)[sel], t_pad),
        "t_end": jnp.where(valid, t_end.reshape(-1)[sel], t_pad),
        "valid": valid,
        "n_valid": jnp.minimum(n_cand, max_samples),
        "n_candidates": n_cand,
        "ray_counts": counts,
        "complete": jnp.cumsum(counts) <= max_samples,
    }
