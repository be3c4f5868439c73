"""Classic 3DGS adaptive density control (Kerbl et al. 2023) inside a fixed capacity of slots.

3DGS grows and shrinks its arrays; here N is fixed (static shapes, one compiled step) and an
`active` mask [N] says which slots hold a Gaussian. Inactive slots are culled before
rasterisation (radius 0: no pixels, no gradient) and reused by clones and splits.

Statistics, accumulated over the steps between two densifications for visible Gaussians
(radius > 0): the norm of the view-space positional gradient in NDC units,
g = |dL/dmu' * (W/2, H/2)| (mu' the pixel coordinates: NDC spans W/2 px per unit), its
count, and the largest screen radius seen.

Every `window.every` steps from `window.start` until progress `window.until` (strategy.Classic;
3DGS: every 100 steps from 500 to 15000 of 30000), with E the scene extent:

    mean g >= grad_threshold (2e-4) and max scale <= percent_dense E (0.01 E):  clone (a copy)
    mean g >= grad_threshold and max scale > percent_dense E:  split into 2 Gaussians at
        mu + R S eps (eps ~ N(0, I)), scales / 1.6, other parameters copied (the parent's slot
        holds one of them)
    then prune: o < 0.005, and after the first opacity reset also screen radius > max_screen
        or max scale > 0.1 E (3DGS: after step 3000, its first reset; so with the reset off, the
        default here, only the opacity prune runs: the lego figures below were measured so).

Clones and splits need one free slot each; when there are fewer free slots than candidates
the largest gradients win (3DGS would just grow). With reset_every > 0, every `reset_every`
steps all opacities are clamped to at most 0.01 (3DGS: every 3000 of 30k steps). Off by default:
a 10-minute CPU run is ~6000 steps, and on lego its one reset (step 3000) took ~1000 steps to
recover from 9.9 dB and ended 1.2 dB lower (32.98 against 34.20 dB on all 50 views of val[50:100],
benchmarks/lego_cli.py --preset splat, one sitting). Adam moments of every written slot are reset.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.project import quaternion_to_rotation


@dataclass(frozen=True)
class ClassicSchedule:
    """The thresholds of classic density control (its timing: train.SplatConfig's control_* fields)."""

    reset_every: int = 0  # steps between opacity resets; 0: none (see the module docstring)
    grad_threshold: float = 2e-4
    percent_dense: float = 0.01
    min_opacity: float = 0.005
    max_screen_frac: float = 20 / 800  # 3DGS's 20 px screen-size prune at 800 px, as a fraction of the width
    reset_opacity: float = 0.01


def zero_stats(n: int) -> dict:
    """Fresh statistics: grad_sum [N], count [N], max_radius [N] (float32)."""
    return {"grad_sum": jnp.zeros(n, jnp.float32), "count": jnp.zeros(n, jnp.float32),
            "max_radius": jnp.zeros(n, jnp.float32)}


def accumulate(stats: dict, grad_means2d, radii, width: int, height: int) -> dict:
    """Add one view's NDC gradient norms [N] (from dL/dmeans2d [N, 2]) and radii [N] to the statistics (jittable)."""
    vis = radii > 0
    g = jnp.linalg.norm(grad_means2d * jnp.array([0.5 * width, 0.5 * height], grad_means2d.dtype), axis=-1)
    return {"grad_sum": stats["grad_sum"] + jnp.where(vis, g, 0.0),
            "count": stats["count"] + vis.astype(jnp.float32),
            "max_radius": jnp.maximum(stats["max_radius"], jnp.where(vis, radii, 0).astype(jnp.float32))}


def _split_samples(params: dict, idx: np.ndarray, rng) -> np.ndarray:
    """One position sample mu + R S eps [M, 3] for each Gaussian idx [M]."""
    rot = np.asarray(quaternion_to_rotation(jnp.asarray(params["quats"][idx])), np.float64)
    s = np.exp(params["log_scales"][idx].astype(np.float64))
    eps = rng.normal(size=(len(idx), 3))
    return (params["means"][idx] + np.einsum("nij,nj->ni", rot, s * eps)).astype(np.float32)


def densify(params: dict, active: np.ndarray, stats: dict, extent: float, rng, sched: ClassicSchedule,
            width: int, after_reset: bool) -> tuple[dict, np.ndarray, np.ndarray]:
    """Clone, split and prune once (see module docstring); numpy in, numpy out.

    Returns (params, active, touched slots [M] whose Adam moments the caller resets)."""
    p = {k: np.array(v) for k, v in params.items()}
    active = active.copy()
    count = np.asarray(stats["count"])
    grad = np.where(count > 0, np.asarray(stats["grad_sum"]) / np.maximum(count, 1), 0.0)
    big = np.exp(p["log_scales"]).max(-1) > sched.percent_dense * extent
    cand = np.flatnonzero(active & (grad >= sched.grad_threshold))
    cand = cand[np.argsort(-grad[cand], kind="stable")]
    free = np.flatnonzero(~active)
    cand = cand[: len(free)]
    clone, split = cand[~big[cand]], cand[big[cand]]
    dst_clone, dst_split = free[: len(clone)], free[len(clone): len(cand)]
    for k in p:
        p[k][dst_clone] = p[k][clone]
    if len(split):
        first, second = _split_samples(p, split, rng), _split_samples(p, split, rng)
        for k in p:
            p[k][dst_split] = p[k][split]
        p["means"][split], p["means"][dst_split] = first, second
        shrunk = p["log_scales"][split] - np.float32(np.log(1.6))
        p["log_scales"][split] = shrunk
        p["log_scales"][dst_split] = shrunk
    active[dst_clone] = True
    active[dst_split] = True
    o = 1.0 / (1.0 + np.exp(-p["opacity"].astype(np.float64)))
    prune = active & (o < sched.min_opacity)
    if after_reset:
        radius = np.asarray(stats["max_radius"])
        prune |= active & (radius > sched.max_screen_frac * width)
        prune |= active & (np.exp(p["log_scales"]).max(-1) > 0.1 * extent)
    active &= ~prune
    touched = np.concatenate([clone, dst_clone, split, dst_split]).astype(np.int64)
    return p, active, touched


def reset_opacity(params: dict, value: float = 0.01) -> dict:
    """Opacities clamped to at most `value` (the logit of it), numpy."""
    p = dict(params)
    cap = np.float32(np.log(value) - np.log1p(-value))
    p["opacity"] = np.minimum(np.asarray(params["opacity"]), cap)
    return p
