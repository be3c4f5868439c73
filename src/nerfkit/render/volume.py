"""Volume rendering: the discrete render equation of NeRF (Max 1995; Mildenhall et al. 2020).

Samples t_1 < ... < t_N along a ray o + t d with densities sigma_i and colours c_i:

    delta_i = (t_{i+1} - t_i) |d|          (world-space length of sample i's interval)
    alpha_i = 1 - exp(-sigma_i delta_i)
    T_i     = prod_{j<i} (1 - alpha_j) = exp(-sum_{j<i} sigma_j delta_j)
    w_i     = T_i alpha_i
    colour  = sum_i w_i c_i + (1 - sum_i w_i) * background
    depth   = sum_i w_i t_i                 (z-depth, see cameras.py)
    opacity = sum_i w_i  (= 1 - T_{N+1} <= 1)
    median  = t_j, j the first sample with sum_{i<=j} w_i >= opacity / 2

The median depth is the median of where the ray ends, given that it ends (as depth / opacity is
the mean): a surface's depth, where the expected depth mixes the surfaces a ray meets (a ray that
grazes a soft edge and goes on to the floor gets a depth between the two); and, unlike the point
where the ray turns half opaque, it stays inside a soft surface of opacity a little over 1/2 rather
than at its far end. Rays with (almost) no opacity get the far end, as depth_normalized does.

The last sample's interval is the nominal bin width (far - near) / N rather than the
original NeRF's 1e10: with 1e10 every ray becomes opaque at its last sample, which
makes opacity meaningless and forces the field to paint the background; with a finite
interval, rays through empty space keep opacity ~0 and show the background colour.
Both a dense form ([R, N] samples per ray) and a packed form (a flat list of samples with
ray indices, for fields that skip empty space) are provided.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def sample_intervals(t: jnp.ndarray, last_interval: float) -> jnp.ndarray:
    """Interval lengths in t [..., N]: t_{i+1} - t_i, and `last_interval` for the last sample."""
    last = jnp.full_like(t[..., :1], last_interval)
    return jnp.concatenate([t[..., 1:] - t[..., :-1], last], axis=-1)


def compositing_weights(sigma: jnp.ndarray, delta: jnp.ndarray) -> jnp.ndarray:
    """w_i = T_i (1 - exp(-sigma_i delta_i)) for densities and interval lengths [..., N]."""
    tau = sigma * delta  # optical depth of each interval
    alpha = 1.0 - jnp.exp(-tau)
    trans = jnp.exp(-jnp.concatenate([jnp.zeros_like(tau[..., :1]), jnp.cumsum(tau[..., :-1], axis=-1)], axis=-1))
    return trans * alpha


def composite(weights: jnp.ndarray, rgb: jnp.ndarray, t: jnp.ndarray, background: jnp.ndarray) -> dict:
    """Accumulate per-sample weights [..., N], colours [..., N, 3], distances [..., N].

    Returns rgb [..., 3] (on `background` [3]), depth [...] (sum w t), opacity [...],
    depth_normalized [...] = depth / opacity (the expected depth given a hit; far
    where the ray hits nothing, which cannot be told apart from the opacity alone) and
    depth_median [...] (module docstring; far where the ray hits nothing).
    """
    opacity = jnp.sum(weights, axis=-1)
    color = jnp.sum(weights[..., None] * rgb, axis=-2) + (1.0 - opacity[..., None]) * background
    depth = jnp.sum(weights * t, axis=-1)
    depth_norm = jnp.where(opacity > 1e-6, depth / jnp.maximum(opacity, 1e-6), t[..., -1])
    cum = jnp.cumsum(weights, axis=-1)
    j = jnp.argmax(cum >= 0.5 * opacity[..., None], axis=-1)
    median = jnp.where(opacity > 1e-6, jnp.take_along_axis(t, j[..., None], axis=-1)[..., 0], t[..., -1])
    return {"rgb": color, "depth": depth, "opacity": opacity, "depth_normalized": depth_norm, "depth_median": median}


def volume_render(sigma, rgb, t, dir_norm, last_interval, background) -> dict:
    """Dense render of samples [R, N] (sigma, t), [R, N, 3] (rgb) for rays with |d| [R].

    Returns composite(...) plus the weights [R, N] (hierarchical sampling needs them).
    """
    delta = sample_intervals(t, last_interval) * dir_norm[..., None]
    w = compositing_weights(sigma, delta)
    out = composite(w, rgb, t, background)
    out["weights"] = w
    return out


# ---------------------------------------------------------------------------------------
# Packed form: S samples in one flat list, sorted by ray then t; ray_idx [S] names the ray.


def segment_starts(ray_idx: jnp.ndarray) -> jnp.ndarray:
    """bool [S]: True where a new ray's run of samples begins in a packed list."""
    return jnp.concatenate([jnp.ones(1, bool), ray_idx[1:] != ray_idx[:-1]])


def segmented_cumsum(x: jnp.ndarray, starts: jnp.ndarray) -> jnp.ndarray:
    """Inclusive running sum of x [S] that restarts wherever `starts` is True.

    A segmented scan (associative operator on (sum, restarted) pairs), so each ray's sum is
    accumulated from its own samples only: no large batch-wide prefix is subtracted,
    which would lose float32 precision after many opaque rays.
    """

    def op(a, b):
        a_sum, a_flag = a
        b_sum, b_flag = b
        return jnp.where(b_flag, b_sum, a_sum + b_sum), a_flag | b_flag

    out, _ = jax.lax.associative_scan(op, (x, starts))
    return out


def packed_compositing_weights(sigma, delta, ray_idx, valid, min_transmittance: float = 0.0):
    """w_i of packed samples [S] sorted by ray; invalid samples get weight 0 and no optical depth.

    T_i = exp(-sum_{j<i, same ray} sigma_j delta_j). Samples whose transmittance is already
    below `min_transmittance` get weight 0 (early ray termination).
    """
    tau = jnp.where(valid, sigma * delta, 0.0)
    trans = jnp.exp(-(segmented_cumsum(tau, segment_starts(ray_idx)) - tau))
    w = trans * (1.0 - jnp.exp(-tau))
    return jnp.where(valid & (trans >= min_transmittance), w, 0.0)


def packed_composite(weights, rgb, t, ray_idx, n_rays: int, background, far) -> dict:
    """Per-ray rgb [n_rays, 3], depth, opacity, depth_normalized and depth_median from packed samples [S]
    sorted by ray then t.

    As `composite`; depth_normalized and depth_median are `far` for rays with (almost) no opacity.
    The median's sample is the one where the ray's running opacity crosses half its opacity A:
    sum_{i<j} w_i < A / 2 <= sum_{i<=j} w_i (one per ray).
    """
    opacity = jax.ops.segment_sum(weights, ray_idx, n_rays)
    color = jax.ops.segment_sum(weights[:, None] * rgb, ray_idx, n_rays) + (1.0 - opacity[:, None]) * background
    depth = jax.ops.segment_sum(weights * t, ray_idx, n_rays)
    depth_norm = jnp.where(opacity > 1e-6, depth / jnp.maximum(opacity, 1e-6), far)
    starts = segment_starts(ray_idx)
    cum = segmented_cumsum(weights, starts)
    before = jnp.where(starts, 0.0, jnp.roll(cum, 1))  # the running sum before each sample, in its ray
    half = 0.5 * opacity[ray_idx]
    crossing = (before < half) & (cum >= half)
    median = jax.ops.segment_sum(jnp.where(crossing, t, 0.0), ray_idx, n_rays)
    median = jnp.where(opacity > 1e-6, median, far)
    return {"rgb": color, "depth": depth, "opacity": opacity, "depth_normalized": depth_norm, "depth_median": median}
