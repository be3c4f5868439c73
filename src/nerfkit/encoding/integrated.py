"""Integrated positional encoding (mip-NeRF, Barron et al. 2021, sec. 3.1, eq. 14).

The expected positional encoding of a Gaussian x ~ N(mu, sigma^2), per coordinate: for
frequency f,

    E[sin(f x)] = sin(f mu) exp(-f^2 sigma^2 / 2),   E[cos(f x)] = cos(f mu) exp(-f^2 sigma^2 / 2)

so frequencies whose period is small against the Gaussian's extent fade out (anti-aliasing).
Same layout and frequencies f_k = 2^k pi as positional.positional_encoding, whose value it
takes as sigma -> 0: [mu, sin(f_0 mu) e_0, cos(f_0 mu) e_0, ...] with e_k = exp(-f_k^2 sigma^2 / 2).
The diagonal of the covariance is enough (the encoding is per coordinate).
"""

from __future__ import annotations

import jax.numpy as jnp


def integrated_positional_encoding(mean: jnp.ndarray, var: jnp.ndarray, n_freqs: int) -> jnp.ndarray:
    """E[gamma(x)] for x ~ N(mean, diag(var)): [..., C] (twice) -> [..., C * (1 + 2 * n_freqs)]."""
    freqs = (2.0 ** jnp.arange(n_freqs, dtype=mean.dtype)) * jnp.pi  # [L]
    x = mean[..., None, :] * freqs[:, None]  # [..., L, C]
    damp = jnp.exp(-0.5 * var[..., None, :] * freqs[:, None] ** 2)  # [..., L, C]
    sc = jnp.stack([jnp.sin(x) * damp, jnp.cos(x) * damp], axis=-2)  # [..., L, 2, C]
    return jnp.concatenate([mean, sc.reshape(*mean.shape[:-1], -1)], axis=-1)
