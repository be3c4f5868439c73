"""Tests for the NeRF positional encoding (nerfkit.encoding.positional).

The reference is a direct float64 numpy transcription of
    gamma(p) = [p, sin(2^0 pi p), cos(2^0 pi p), ..., sin(2^{L-1} pi p), cos(2^{L-1} pi p)]
with each block C wide. JAX works in float32: the argument 2^k pi p (|p| <= 1, k <= 3,
so |arg| <= 8 pi ~ 25) carries a relative rounding error of a few 2^-24, i.e. an absolute
error of ~25 * 3 * 6e-8 ~ 5e-6 in the argument and hence in sin / cos: atol 1e-5.
"""

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.encoding.positional import encoded_size, positional_encoding


def reference_encoding(p: np.ndarray, n_freqs: int) -> np.ndarray:
    p = np.asarray(p, np.float64)
    blocks = [p]
    for k in range(n_freqs):
        blocks.append(np.sin(2.0**k * np.pi * p))
        blocks.append(np.cos(2.0**k * np.pi * p))
    return np.concatenate(blocks, axis=-1)


def test_matches_direct_formula_on_random_inputs():
    rng = np.random.default_rng(0)
    p = rng.uniform(-1.0, 1.0, size=(5, 7, 3)).astype(np.float32)
    out = np.asarray(positional_encoding(jnp.asarray(p), 4))
    assert out.shape == (5, 7, 3 * (1 + 2 * 4))
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, reference_encoding(p, 4), atol=1e-5, rtol=0)
    # The identity block is p itself, bit for bit.
    np.testing.assert_array_equal(out[..., :3], p)


def test_exact_values_and_layout_for_small_input():
    # p = (0.5, 0.25): args pi/2, pi, 2 pi for p=0.5 and pi/4, pi/2, pi for p=0.25.
    p = jnp.array([0.5, 0.25], jnp.float32)
    out = np.asarray(positional_encoding(p, 3))
    s2 = np.sqrt(0.5)
    expected = [
        0.5, 0.25,            # p
        1.0, s2,              # sin(pi p)
        0.0, s2,              # cos(pi p)
        0.0, 1.0,             # sin(2 pi p)
        -1.0, 0.0,            # cos(2 pi p)
        0.0, 0.0,             # sin(4 pi p)
        1.0, -1.0,            # cos(4 pi p)
    ]
    np.testing.assert_allclose(out, expected, atol=1e-6)


def test_zero_input_encodes_to_sines_zero_cosines_one():
    out = np.asarray(positional_encoding(jnp.zeros((2, 3)), 5))
    blocks = out.reshape(2, 1 + 2 * 5, 3)
    np.testing.assert_array_equal(blocks[:, 0], 0.0)
    np.testing.assert_array_equal(blocks[:, 1::2], 0.0)  # sin
    np.testing.assert_array_equal(blocks[:, 2::2], 1.0)  # cos


@pytest.mark.parametrize("c, n_freqs", [(3, 10), (3, 4), (2, 1), (1, 0), (4, 6)])
def test_output_size_is_c_times_1_plus_2l(c, n_freqs):
    x = jnp.ones((2, c), jnp.float32) * 0.1
    out = positional_encoding(x, n_freqs)
    assert out.shape == (2, c * (1 + 2 * n_freqs))
    assert encoded_size(c, n_freqs) == c * (1 + 2 * n_freqs)
    assert encoded_size(c, n_freqs, enabled=False) == c
    assert encoded_size(3, 10) == 63 and encoded_size(3, 4) == 27


def test_disabled_and_zero_frequencies_are_identity():
    rng = np.random.default_rng(1)
    p = jnp.asarray(rng.normal(size=(4, 3)).astype(np.float32))
    np.testing.assert_array_equal(np.asarray(positional_encoding(p, 10, enabled=False)), np.asarray(p))
    np.testing.assert_array_equal(np.asarray(positional_encoding(p, 0)), np.asarray(p))
    assert positional_encoding(p, 0).shape == (4, 3)


def test_broadcasts_over_leading_dims():
    rng = np.random.default_rng(2)
    p = rng.uniform(-1, 1, size=(2, 3, 4, 3)).astype(np.float32)
    full = np.asarray(positional_encoding(jnp.asarray(p), 2))
    flat = np.asarray(positional_encoding(jnp.asarray(p.reshape(-1, 3)), 2))
    np.testing.assert_allclose(full.reshape(-1, 15), flat, atol=1e-7)
