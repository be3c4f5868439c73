"""Integrated positional encoding: Monte Carlo expectations, and the limit of zero variance."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from nerfkit.encoding.integrated import integrated_positional_encoding
from nerfkit.encoding.positional import positional_encoding


def test_ipe_is_the_expected_encoding_of_a_gaussian():
    """E[sin(f x)], E[cos(f x)] of x ~ N(mu, sigma^2) by Monte Carlo (10^6 draws: error < 3e-3)."""
    rng = np.random.default_rng(0)
    mean = np.array([0.3, -0.7, 0.05])
    var = np.array([0.01, 0.002, 0.05])
    x = mean + np.sqrt(var) * rng.standard_normal((1_000_000, 3))
    freqs = 2.0 ** np.arange(4) * np.pi
    mc = [x.mean(0)]
    for f in freqs:
        mc += [np.sin(f * x).mean(0), np.cos(f * x).mean(0)]
    got = np.asarray(integrated_positional_encoding(jnp.asarray(mean, jnp.float32), jnp.asarray(var, jnp.float32), 4))
    np.testing.assert_allclose(got, np.concatenate(mc), atol=3e-3)
    # The finest frequencies of the widest coordinate are damped away (the anti-aliasing).
    assert abs(got[3 + 6 * 3 + 2]) < 1e-3 and abs(got[3 + 7 * 3 + 2]) < 1e-3


def test_ipe_tends_to_pe_as_the_variance_vanishes():
    p = jnp.asarray(np.random.default_rng(1).uniform(-1, 1, (50, 3)), jnp.float32)
    pe = np.asarray(positional_encoding(p, 10))
    f_max = 2.0**9 * np.pi
    gaps = []
    for v in (1e-5, 1e-7, 1e-9, 0.0):
        ipe = np.asarray(integrated_positional_encoding(p, jnp.full_like(p, v), 10))
        gaps.append(np.abs(ipe - pe).max())
        assert gaps[-1] <= 1.0 - np.exp(-0.5 * f_max**2 * v) + 1e-5  # |sin| <= 1 times the missing damping
    assert gaps[0] > 0.5 and gaps[-1] < 1e-6 and gaps == sorted(gaps, reverse=True)
