"""Tests for stratified and inverse-CDF (importance) sampling (nerfkit.sampling.intervals).

Float32 tolerances: sample distances are at most ~6, where one float32 ulp is 4.8e-7,
so bin-membership checks allow 1e-6 (~2 ulp) of slack at the bin edges.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.sampling.intervals import midpoints, stratified_samples
from nerfkit.sampling.intervals import sample_pdf as _sample_pdf

# One compilation per shape instead of op-by-op dispatch (much faster on a small CPU).
sample_pdf = jax.jit(_sample_pdf, static_argnums=(3, 4))

ULP_SLACK = 1e-6


def test_stratified_samples_lie_in_their_bins_and_are_sorted():
    near, far, n, r = 2.0, 6.0, 32, 256
    t = np.asarray(stratified_samples(jax.random.PRNGKey(0), r, n, near, far, perturb=True))
    assert t.shape == (r, n) and t.dtype == np.float32
    w = (far - near) / n
    k = np.arange(n)
    lo, hi = near + k * w, near + (k + 1) * w
    assert np.all(t >= lo - ULP_SLACK)
    assert np.all(t < hi + ULP_SLACK)
    assert np.all(np.diff(t, axis=-1) > 0)
    # The offsets u = (t - lo) / w fill each bin: uniform on [0, 1) (8192 draws:
    # mean 0.5 +- 3.2e-3 standard error; extremes within 1e-2 of the ends with
    # probability 1 - 2 * 0.99^8192 ~ 1).
    u = (t - lo) / w
    assert abs(u.mean() - 0.5) < 0.02
    assert u.min() < 0.01 and u.max() > 0.99
    # Every ray draws its own offsets.
    assert not np.allclose(u[0], u[1])


def test_stratified_without_perturbation_gives_bin_midpoints_exactly():
    near, far, n = 2.0, 6.0, 64
    t = np.asarray(stratified_samples(jax.random.PRNGKey(0), 3, n, near, far, perturb=False))
    w = np.float32((far - near) / n)
    expected = np.float32(near) + (np.arange(n, dtype=np.float32) + np.float32(0.5)) * w  # same float32 ops
    np.testing.assert_array_equal(t, np.broadcast_to(expected, (3, n)))
    # Against the float64 midpoints, within float32 rounding.
    np.testing.assert_allclose(t[0], near + (np.arange(n) + 0.5) * (far - near) / n, atol=ULP_SLACK, rtol=0)
    # Deterministic: the key does not matter.
    t2 = np.asarray(stratified_samples(jax.random.PRNGKey(123), 3, n, near, far, perturb=False))
    np.testing.assert_array_equal(t, t2)


def test_stratified_keys_control_the_randomness():
    args = (8, 16, 0.0, 5.0, True)
    a = np.asarray(stratified_samples(jax.random.PRNGKey(1), *args))
    b = np.asarray(stratified_samples(jax.random.PRNGKey(1), *args))
    c = np.asarray(stratified_samples(jax.random.PRNGKey(2), *args))
    np.testing.assert_array_equal(a, b)
    assert np.mean(a != c) > 0.99  # continuous draws: equal only by chance


def test_midpoints():
    t = jnp.array([[0.0, 1.0, 3.0, 7.0]])
    np.testing.assert_array_equal(np.asarray(midpoints(t)), [[0.5, 2.0, 5.0]])


# --- sample_pdf ----------------------------------------------------------------------------


def random_bins(rng, r, m, lo=2.0, hi=6.0):
    inner = np.sort(rng.uniform(lo, hi, size=(r, m - 1)), axis=-1)
    return np.concatenate([np.full((r, 1), lo), inner, np.full((r, 1), hi)], axis=-1).astype(np.float32)


@pytest.mark.parametrize("deterministic", [False, True])
def test_sample_pdf_within_range_and_sorted(deterministic):
    rng = np.random.default_rng(0)
    r, m, n = 16, 12, 64
    bins = random_bins(rng, r, m)
    weights = rng.exponential(size=(r, m)).astype(np.float32)
    weights[0] = 0.0  # an empty ray: uniform by the epsilon
    t = np.asarray(sample_pdf(jax.random.PRNGKey(3), jnp.asarray(bins), jnp.asarray(weights), n, deterministic))
    assert t.shape == (r, n)
    assert np.all(t >= bins[:, :1]) and np.all(t <= bins[:, -1:])
    assert np.all(np.diff(t, axis=-1) >= 0)


def test_sample_pdf_concentrates_in_the_only_weighted_bin():
    # All weight in bin k of M. sample_pdf adds 1e-5 to every weight, so each other bin has
    # probability 1e-5 / (1 + M 1e-5): with M = 16 the chance to land outside bin k is
    # 15e-5 / 1.00016 ~ 1.5e-4 per sample. Of R * n = 8 * 1000 samples the expected count
    # outside is ~1.2 (Poisson); more than 12 has probability < 1e-9.
    r, m, n, k = 8, 16, 1000, 5
    bins = jnp.broadcast_to(jnp.linspace(2.0, 6.0, m + 1), (r, m + 1))
    weights = jnp.zeros((r, m)).at[:, k].set(1.0)
    lo, hi = float(bins[0, k]), float(bins[0, k + 1])
    t = np.asarray(sample_pdf(jax.random.PRNGKey(0), bins, weights, n, deterministic=False))
    outside = np.sum((t < lo - ULP_SLACK) | (t > hi + ULP_SLACK))
    assert outside <= 12
    # Inside the bin the pdf is uniform: the samples spread over it.
    inside = t[(t >= lo) & (t <= hi)]
    assert abs((inside.mean() - lo) / (hi - lo) - 0.5) < 0.02  # 8000 uniform draws: s.e. 3.2e-3
    # Deterministic quantiles u = linspace(0, 1, n): only u = 0 and u = 1 fall outside the
    # cdf interval [~k 1e-5, ~1 - (M-k-1) 1e-5] of bin k; they map to the range ends.
    td = np.asarray(sample_pdf(None, bins, weights, n, deterministic=True))
    assert np.all((td[:, 1:-1] >= lo - ULP_SLACK) & (td[:, 1:-1] <= hi + ULP_SLACK))
    np.testing.assert_allclose(td[:, 0], 2.0)
    np.testing.assert_allclose(td[:, -1], 6.0)


def test_sample_pdf_deterministic_uniform_pdf_gives_linspace():
    # Equal weights on equal bins: the cdf is linear, so the evenly spaced quantiles map to
    # evenly spaced distances. float32 cumsum of 1/M over M = 16 bins errs by <~ M eps,
    # which after division by the bin's cdf width 1/M and scaling by its width 4/M gives
    # <~ 4 M eps ~ 4e-6 in t: atol 1e-5.
    r, m, n = 3, 16, 33
    bins = jnp.broadcast_to(jnp.linspace(2.0, 6.0, m + 1), (r, m + 1))
    weights = jnp.full((r, m), 0.7)
    t = np.asarray(sample_pdf(None, bins, weights, n, deterministic=True))
    np.testing.assert_allclose(t, np.broadcast_to(np.linspace(2.0, 6.0, n), (r, n)), atol=1e-5, rtol=0)
    # Non-uniform bins, uniform mass per bin: the quantile u lands in bin floor(u M) at
    # fraction frac(u M): t = bins[k] + frac * (bins[k+1] - bins[k]).
    rng = np.random.default_rng(4)
    b = random_bins(rng, r, m)
    t = np.asarray(sample_pdf(None, jnp.asarray(b), weights, n, deterministic=True))
    u = np.linspace(0.0, 1.0, n) * m
    kk = np.minimum(np.floor(u).astype(int), m - 1)
    frac = u - kk
    expected = b[:, kk] + frac * (b[:, kk + 1] - b[:, kk])
    # Bins as narrow as ~1e-3 amplify the cdf rounding less than the 4/M above: same bound.
    np.testing.assert_allclose(t, expected, atol=1e-5, rtol=0)


def test_sample_pdf_follows_a_two_bin_pdf_in_distribution():
    # Weights 1 : 3 on two equal bins [0, 1), [1, 2): P(t < 1) = 1/4 (+ tiny epsilon share).
    r, n = 64, 256
    bins = jnp.broadcast_to(jnp.array([0.0, 1.0, 2.0]), (r, 3))
    weights = jnp.broadcast_to(jnp.array([1.0, 3.0]), (r, 2))
    t = np.asarray(sample_pdf(jax.random.PRNGKey(5), bins, weights, n, deterministic=False))
    frac_low = np.mean(t < 1.0)
    assert abs(frac_low - 0.25) < 0.01  # 16384 draws: s.e. 3.4e-3
    # Deterministic: exactly the quantiles of the piecewise-linear cdf.
    td = np.asarray(sample_pdf(None, bins[:1], weights[:1], 5, deterministic=True))[0]
    u = np.linspace(0, 1, 5)
    expected = np.where(u < 0.25, u / 0.25, 1.0 + (u - 0.25) / 0.75)
    np.testing.assert_allclose(td, expected, atol=1e-4)  # epsilon 1e-5 shifts the cdf by < 1e-5 / 4 relative


def test_sample_pdf_keys_and_no_gradient():
    bins = jnp.broadcast_to(jnp.linspace(0.0, 1.0, 5), (2, 5))
    weights = jnp.array([[1.0, 2.0, 3.0, 4.0], [4.0, 3.0, 2.0, 1.0]])
    a = sample_pdf(jax.random.PRNGKey(0), bins, weights, 10, False)
    b = sample_pdf(jax.random.PRNGKey(1), bins, weights, 10, False)
    assert not np.allclose(np.asarray(a), np.asarray(b))
    g = jax.jit(jax.grad(lambda w: jnp.sum(_sample_pdf(jax.random.PRNGKey(0), bins, w, 10, False))))(weights)
    np.testing.assert_array_equal(np.asarray(g), 0.0)


def test_stratified_edges_cover_near_to_far_in_order():
    from nerfkit.sampling.intervals import stratified_edges

    e = np.asarray(stratified_edges(None, 3, 8, 2.0, 6.0, perturb=False))
    np.testing.assert_allclose(e, np.broadcast_to(np.linspace(2, 6, 9), (3, 9)), atol=1e-6)
    e = np.asarray(stratified_edges(jax.random.PRNGKey(0), 500, 8, 2.0, 6.0, perturb=True))
    assert e.shape == (500, 9) and np.all(np.diff(e, axis=-1) >= 0)
    assert e.min() >= 2.0 and e.max() <= 6.0
    # Each edge stays between the midpoints around it, and is uniform there (mean at the even edge).
    even = np.linspace(2, 6, 9)
    assert np.all(np.abs(e[:, 1:-1] - even[1:-1]) <= 0.25 + 1e-6)
    np.testing.assert_allclose(e[:, 1:-1].mean(0), even[1:-1], atol=0.05)


def test_blur_weights_widen_a_spike_into_its_neighbours():
    from nerfkit.sampling.intervals import blur_weights

    w = jnp.asarray([[0.0, 0.0, 1.0, 0.0, 0.0], [0.2, 0.1, 0.0, 0.0, 0.7]])
    np.testing.assert_allclose(blur_weights(w, 0.0), [[0, 0.5, 1, 0.5, 0], [0.2, 0.15, 0.05, 0.35, 0.7]], atol=1e-7)
    np.testing.assert_allclose(blur_weights(w, 0.01) - blur_weights(w, 0.0), 0.01, atol=1e-7)
