"""Proposal sampling's pieces (nerfkit.sampling.proposal) against brute-force references written here."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.sampling import proposal as P


def _random_edges(rng, r, n, lo=0.0, hi=2.0):
    inner = np.sort(rng.uniform(lo, hi, (r, n - 1)), axis=1)
    return np.concatenate([np.full((r, 1), lo), inner, np.full((r, 1), hi)], 1).astype(np.float32)


def test_uniform_edges_tile_the_range_evenly_and_jitter_shifts_them_alike():
    e = np.asarray(P.uniform_edges(jax.random.PRNGKey(0), 3, 8, 0.5, 1.5, jitter=False))
    assert np.allclose(e, np.linspace(0.5, 1.5, 9)[None].repeat(3, 0), atol=1e-6)
    j = np.asarray(P.uniform_edges(jax.random.PRNGKey(1), 500, 8, 0.5, 1.5, jitter=True))
    assert np.all(np.diff(j, axis=1) >= 0) and np.all(j[:, 0] == 0.5) and np.all(j[:, -1] == 1.5)
    shift = j[:, 1:-1] - np.linspace(0.5, 1.5, 9)[1:-1]
    assert np.allclose(shift, shift[:, :1], atol=1e-6)  # one offset per ray
    assert np.abs(shift).max() <= 0.0625 + 1e-6 and shift[:, 0].std() > 0.03  # within half a bin, U[-1/2, 1/2)


def test_resampled_edges_crowd_where_the_weight_is_and_still_tile_the_range():
    edges = jnp.asarray(np.linspace(0.0, 2.0, 11, dtype=np.float32)[None])  # 10 bins of 0.2
    w = jnp.zeros((1, 10)).at[0, 6].set(1.0)  # all the weight in [1.2, 1.4]
    new = np.asarray(P.resample_edges(jax.random.PRNGKey(0), edges, w, 32, jitter=False))[0]
    assert new[0] == 0.0 and new[-1] == 2.0 and np.all(np.diff(new) >= 0)
    inside = np.mean((new > 1.2) & (new < 1.4))
    # Mass of the bin: 1 / (1 + 10 x padding) of the CDF; the other bins share the padding's.
    assert inside == pytest.approx(1.0 / (1.0 + 10 * P.HISTOGRAM_PADDING), abs=0.05)
    flat = np.asarray(P.resample_edges(jax.random.PRNGKey(0), edges, jnp.ones((1, 10)), 20, jitter=False))[0]
    assert np.allclose(np.diff(flat[1:-1]), 2.0 / 21, atol=1e-5)  # uniform weights: evenly spaced draws


def test_weights_bound_sums_the_envelope_over_overlapping_intervals():
    rng = np.random.default_rng(0)
    e, f = _random_edges(rng, 6, 9), _random_edges(rng, 6, 13)
    fw = rng.uniform(0, 1, (6, 13)).astype(np.float32)
    got = np.asarray(P.weights_bound(jnp.asarray(e), jnp.asarray(f), jnp.asarray(fw)))
    ref = np.zeros((6, 9))
    for r in range(6):
        for k in range(9):
            overlap = (f[r, :-1] < e[r, k + 1]) & (f[r, 1:] > e[r, k])
            ref[r, k] = fw[r, overlap].sum()
    assert np.allclose(got, ref, atol=1e-5)


def test_interlevel_loss_is_zero_for_a_covering_proposal_and_moves_only_the_proposal():
    rng = np.random.default_rng(1)
    e = jnp.asarray(_random_edges(rng, 4, 16))
    w = jnp.asarray(rng.uniform(0, 0.1, (4, 16)).astype(np.float32))
    assert float(P.interlevel_loss(e, w, [e], [w])) == pytest.approx(0.0, abs=1e-9)
    short = w.at[:, 5].set(0.0)  # the proposal misses the mass of interval 5
    loss = float(P.interlevel_loss(e, w, [e], [short]))
    assert loss > 0 and loss == pytest.approx(float(jnp.mean(w[:, 5] ** 2 / (w[:, 5] + P.EPS)) / 16), rel=1e-4)
    g_field, g_prop = jax.grad(lambda a, b: P.interlevel_loss(e, a, [e], [b]), argnums=(0, 1))(w, short)
    assert float(jnp.abs(g_field).max()) == 0.0 and float(g_prop[:, 5].min()) < 0


def test_distortion_loss_equals_its_double_sum():
    rng = np.random.default_rng(2)
    e = _random_edges(rng, 3, 7, 0.0, 1.0)
    w = rng.uniform(0, 0.3, (3, 7)).astype(np.float32)
    m = 0.5 * (e[:, 1:] + e[:, :-1])
    ref = np.mean([(w[r, :, None] * w[r, None, :] * np.abs(m[r, :, None] - m[r, None, :])).sum()
                   + (w[r] ** 2 * np.diff(e[r])).sum() / 3 for r in range(3)])
    assert float(P.distortion_loss(jnp.asarray(e), jnp.asarray(w))) == pytest.approx(ref, rel=1e-5)
    # One compact interval costs less than the same weight split between two far apart.
    one = P.distortion_loss(jnp.asarray([[0.0, 0.5, 0.55, 1.0]]), jnp.asarray([[0.0, 1.0, 0.0]]))
    two = P.distortion_loss(jnp.asarray([[0.0, 0.05, 0.95, 1.0]]), jnp.asarray([[0.5, 0.0, 0.5]]))
    assert float(one) < float(two)
