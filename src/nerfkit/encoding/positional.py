"""Positional encoding of the original NeRF (Mildenhall et al. 2020, eq. 4).

    gamma(p) = [p, sin(2^0 pi p), cos(2^0 pi p), ..., sin(2^{L-1} pi p), cos(2^{L-1} pi p)]

applied to each coordinate of p. For p of dimension C the output has C * (1 + 2L) entries
(63 for positions with L=10, 27 for directions with L=4). The frequencies 2^k pi follow
the paper; nerf-pytorch drops the pi, which only rescales the frequency ladder.
"""

from __future__ import annotations

import jax.numpy as jnp


def encoded_size(in_dim: int, n_freqs: int, enabled: bool = True) -> int:
    """Number of features `positional_encoding` returns for `in_dim` inputs."""
    return in_dim * (1 + 2 * n_freqs) if enabled else in_dim


def positional_encoding(p: jnp.ndarray, n_freqs: int, enabled: bool = True) -> jnp.ndarray:
    """gamma(p): [..., C] -> [..., C * (1 + 2 * n_freqs)], or p itself when disabled.

    Layout: [p, sin(f_0 p), cos(f_0 p), sin(f_1 p), cos(f_1 p), ...] with f_k = 2^k pi,
    each block C wide.
    """
    if not enabled or n_freqs == 0:
        return p
    freqs = (2.0 ** jnp.arange(n_freqs, dtype=p.dtype)) * jnp.pi  # [L]
    x = p[..., None, :] * freqs[:, None]  # [..., L, C]
    sc = jnp.stack([jnp.sin(x), jnp.cos(x)], axis=-2)  # [..., L, 2, C]
    return jnp.concatenate([p, sc.reshape(*p.shape[:-1], -1)], axis=-1)
