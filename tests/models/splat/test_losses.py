"""SSIM / D-SSIM loss of splat/losses.py against nerfkit.core.metrics.ssim (skimage), the L1 + D-SSIM mix
and the RMSE pixel term.

Tolerance: 2e-5 absolute on the mean SSIM. Both take the same windowed statistics over the same
valid pixels; the JAX side sums in float32 (~1e-7 relative per term, over 121-tap windows and a
mean over ~10^3-10^4 values), skimage in float64.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.core.metrics import ssim as ssim_metric
from nerfkit.models.splat.losses import (
    band_matrix,
    filter_valid,
    gaussian_window,
    l1,
    photometric_loss,
    rmse,
    ssim,
)


def image_pairs():
    rng = np.random.default_rng(0)
    h, w = 37, 52
    yy, xx = np.mgrid[0:h, 0:w] / 10.0
    smooth = np.stack([0.5 + 0.4 * np.sin(xx + c) * np.cos(yy - c) for c in range(3)], -1)
    yield smooth, np.clip(smooth + 0.05 * rng.normal(size=smooth.shape), 0, 1)  # noisy copy
    yield smooth, np.roll(smooth, 3, axis=1)  # shifted
    yield rng.uniform(size=(24, 30, 3)), rng.uniform(size=(24, 30, 3))  # unrelated noise
    checker = ((np.indices((32, 32)).sum(0) // 4) % 2).astype(np.float64)[..., None].repeat(3, -1)
    yield checker, 0.8 * checker + 0.1  # contrast change


@pytest.mark.parametrize("pair", list(image_pairs()), ids=["noise", "shift", "random", "contrast"])
def test_ssim_matches_nerfkit_metric(pair):
    x, y = pair
    ours = float(ssim(jnp.asarray(x, jnp.float32), jnp.asarray(y, jnp.float32)))
    assert abs(ours - ssim_metric(x, y)) < 2e-5


def test_window_and_band_matrix():
    g = gaussian_window()
    assert g.shape == (11,) and abs(g.sum() - 1) < 1e-6 and np.argmax(g) == 5
    np.testing.assert_allclose(g[5] / g[4], np.exp(1 / (2 * 1.5**2)), rtol=1e-5)
    b = band_matrix(20, g)
    x = np.random.default_rng(1).normal(size=20)
    np.testing.assert_allclose(b @ x, np.convolve(x, g[::-1], mode="valid"), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("h, w", [(11, 12), (31, 43), (42, 42), (75, 64), (97, 130)])
def test_filter_valid_is_the_separable_valid_correlation(h, w):
    """The blocked filter (blocks of FILTER_BLOCK, a block's tail read from the next) against scipy's 2D valid
    correlation with the outer product of the window, on sizes below, at and across the block edges."""
    from scipy.signal import correlate2d

    g = gaussian_window()
    x = np.random.default_rng(h * w).uniform(size=(2, h, w, 3)).astype(np.float32)
    ours = np.asarray(filter_valid(jnp.asarray(x), g))
    assert ours.shape == (2, h - 10, w - 10, 3)
    for m in range(2):
        for c in range(3):
            np.testing.assert_allclose(ours[m, :, :, c], correlate2d(x[m, :, :, c], np.outer(g, g), mode="valid"),
                                       rtol=1e-5, atol=1e-6)


def test_loss_mix_and_gradient():
    rng = np.random.default_rng(2)
    x = jnp.asarray(rng.uniform(size=(20, 24, 3)), jnp.float32)
    y = jnp.asarray(rng.uniform(size=(20, 24, 3)), jnp.float32)
    assert float(photometric_loss(y, y)) == pytest.approx(0.0, abs=1e-6)
    expect = 0.8 * float(l1(x, y)) + 0.2 * (1 - float(ssim(x, y)))
    assert float(photometric_loss(x, y)) == pytest.approx(expect, rel=1e-6)
    g = jax.grad(photometric_loss)(x, y)
    assert g.shape == x.shape and bool(jnp.all(jnp.isfinite(g)))
    # a small step against the gradient lowers the loss
    assert float(photometric_loss(x - 0.05 * g / jnp.abs(g).max(), y)) < float(photometric_loss(x, y))


def test_rmse_fits_the_mean_where_l1_fits_the_median():
    """Views that disagree on a pixel: targets y = (0, 0, 0, 1) for one predicted value c. RMSE's gradient
    vanishes at mean(y) = 0.25 (L1's does not: there it is (3 - 1) / 4 = 0.5); at any c it is the MSE's
    gradient / (2 rmse), and its size stays within L1's (|mean(c - y)| / rmse <= 1)."""
    y = jnp.asarray([0.0, 0.0, 0.0, 1.0], jnp.float32).reshape(1, 4, 1)

    def loss(fn):
        return jax.grad(lambda c: fn(jnp.full_like(y, c), y))

    assert abs(float(loss(rmse)(0.25))) < 1e-6
    assert float(loss(l1)(0.25)) == pytest.approx(0.5, rel=1e-6)
    for c in (-0.3, 0.1, 0.6, 1.2):
        mse_grad = float(jax.grad(lambda c: jnp.mean((jnp.full_like(y, c) - y) ** 2))(c))
        r = float(rmse(jnp.full_like(y, c), y))
        assert float(loss(rmse)(c)) == pytest.approx(mse_grad / (2 * r), rel=1e-5)
        assert abs(float(loss(rmse)(c))) <= 1.0 + 1e-6
    x = jnp.asarray(np.random.default_rng(3).uniform(size=(20, 24, 3)), jnp.float32)
    assert float(photometric_loss(x, y.mean() + 0 * x, 0.0, "rmse")) == pytest.approx(
        float(jnp.sqrt(jnp.mean((x - y.mean()) ** 2))), rel=1e-5)
    assert bool(jnp.all(jnp.isfinite(jax.grad(photometric_loss)(x, x, 0.2, "rmse"))))
