"""Placing samples along rays: stratified sampling and inverse-CDF importance sampling.

A ray r(t) = o + t d is sampled on [near, far]. Stratified sampling splits the interval
into N equal bins and draws one uniform sample per bin (training), or takes the bin
midpoints (evaluation). Hierarchical sampling (NeRF sec. 5.2) treats the coarse weights
as a piecewise-constant PDF over bins and draws more samples where the weights are.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def stratified_samples(key, n_rays: int, n_samples: int, near: float, far: float, perturb: bool) -> jnp.ndarray:
    """Sample distances t [n_rays, n_samples], sorted, one per bin of width (far-near)/N.

    t_k = near + (k + u_k) (far - near) / N with u_k ~ U[0, 1) if `perturb`, else u_k = 1/2.
    """
    k = jnp.arange(n_samples, dtype=jnp.float32)
    if perturb:
        u = jax.random.uniform(key, (n_rays, n_samples), dtype=jnp.float32)
    else:
        u = jnp.full((n_rays, n_samples), 0.5, jnp.float32)
    return near + (k + u) * ((far - near) / n_samples)


def sample_pdf(key, bins: jnp.ndarray, weights: jnp.ndarray, n_samples: int, deterministic: bool) -> jnp.ndarray:
    """Inverse-transform sampling of a piecewise-constant PDF.

    bins: [R, M+1] bin edges (sorted), weights: [R, M] non-negative mass per bin.
    The CDF is built from w / sum(w) (a small epsilon keeps empty rays uniform); samples
    u (uniform, or evenly spaced when deterministic) map to t = bins[k] + (u - cdf[k]) /
    (cdf[k+1] - cdf[k]) * (bins[k+1] - bins[k]) in the bin k where cdf[k] <= u < cdf[k+1].
    Returns [R, n_samples] sorted samples. No gradient flows back through the samples.
    """
    weights = jax.lax.stop_gradient(weights) + 1e-5
    pdf = weights / jnp.sum(weights, axis=-1, keepdims=True)
    cdf = jnp.concatenate([jnp.zeros_like(pdf[..., :1]), jnp.minimum(1.0, jnp.cumsum(pdf, axis=-1))], axis=-1)
    cdf = cdf.at[..., -1].set(1.0)
    r = bins.shape[0]
    if deterministic:
        u = jnp.broadcast_to(jnp.linspace(0.0, 1.0, n_samples, dtype=jnp.float32), (r, n_samples))
    else:
        u = jax.random.uniform(key, (r, n_samples), dtype=jnp.float32)
    idx = jax.vmap(lambda c, q: jnp.searchsorted(c, q, side="right"))(cdf, u)
    below = jnp.clip(idx - 1, 0, cdf.shape[-1] - 2)
    above = below + 1
    cdf_lo = jnp.take_along_axis(cdf, below, -1)
    cdf_hi = jnp.take_along_axis(cdf, above, -1)
    bin_lo = jnp.take_along_axis(bins, below, -1)
    bin_hi = jnp.take_along_axis(bins, above, -1)
    denom = cdf_hi - cdf_lo
    frac = jnp.where(denom > 0, (u - cdf_lo) / jnp.where(denom > 0, denom, 1.0), 0.0)
    t = bin_lo + jnp.clip(frac, 0.0, 1.0) * (bin_hi - bin_lo)
    return jax.lax.stop_gradient(jnp.sort(t, axis=-1))


def midpoints(t: jnp.ndarray) -> jnp.ndarray:
    """Midpoints [..., N-1] between consecutive samples t [..., N]."""
    return 0.5 * (t[..., 1:] + t[..., :-1])


def stratified_edges(key, n_rays: int, n_intervals: int, near: float, far: float, perturb: bool) -> jnp.ndarray:
    """Interval edges t [n_rays, n_intervals + 1], sorted, spanning [near, far] (mip-NeRF's sampling).

    The evenly spaced edges e_k = near + k (far - near) / N, k = 0..N; when `perturb`, each edge moves
    uniformly within [m_{k-1}, m_k] between the midpoints around it (m_{-1} = near, m_N = far), so the
    intervals stay ordered and still cover [near, far] on average.
    """
    e = jnp.linspace(near, far, n_intervals + 1, dtype=jnp.float32)
    e = jnp.broadcast_to(e, (n_rays, n_intervals + 1))
    if not perturb:
        return e
    mids = 0.5 * (e[:, 1:] + e[:, :-1])
    lower = jnp.concatenate([e[:, :1], mids], axis=-1)
    upper = jnp.concatenate([mids, e[:, -1:]], axis=-1)
    return lower + (upper - lower) * jax.random.uniform(key, e.shape, dtype=jnp.float32)


def blur_weights(w: jnp.ndarray, padding: float) -> jnp.ndarray:
    """mip-NeRF's resampling weights [..., N] from interval weights w [..., N] (Barron et al. 2021, eq. 18):

        w'_k = 1/2 (max(w_{k-1}, w_k) + max(w_k, w_{k+1})) + padding      (w_{-1} = w_0, w_N = w_{N-1})

    a 2-tap max filter then a 2-tap blur (a wide, smooth envelope of w, so fine samples also land
    next to a peak), and a floor so empty space keeps a few samples.
    """
    wp = jnp.concatenate([w[..., :1], w, w[..., -1:]], axis=-1)
    m = jnp.maximum(wp[..., :-1], wp[..., 1:])  # [..., N + 1]
    return 0.5 * (m[..., :-1] + m[..., 1:]) + padding
