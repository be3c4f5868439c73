"""PSNR and SSIM, the numbers every result is judged by, against hand-computed cases and independent
implementations (scikit-image's PSNR; SSIM written out here from Wang et al. 2004 with scipy)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from skimage.metrics import peak_signal_noise_ratio

from nerfkit.core.metrics import mse_to_psnr, psnr, ssim


def test_psnr_of_a_known_error_is_exact():
    # Every pixel off by 0.1: MSE = 0.01, PSNR = -10 log10(0.01) = 20 dB exactly (float64 arithmetic).
    a = np.full((4, 5, 3), 0.5)
    assert psnr(a, a + 0.1) == pytest.approx(20.0, abs=1e-9)
    # Half the pixels off by 0.2, half exact: MSE = 0.02, PSNR = 10 log10(50) = 16.9897...
    b = a.copy()
    b[:2] += 0.2
    assert psnr(b, a) == pytest.approx(10 * np.log10(50.0), abs=1e-9)
    assert mse_to_psnr(1e-4) == pytest.approx(40.0)


def test_psnr_matches_scikit_image():
    rng = np.random.default_rng(0)
    for shape in ((8, 8, 3), (37, 21, 3)):
        x = rng.random(shape)
        y = np.clip(x + rng.normal(0, 0.05, shape), 0, 1)
        assert psnr(y, x) == pytest.approx(peak_signal_noise_ratio(x, y, data_range=1.0), abs=1e-9)
        assert psnr(y.astype(np.float32), x.astype(np.float32)) == pytest.approx(psnr(y, x), abs=1e-4)


def test_identical_images_have_ssim_one_and_psnr_at_its_floor():
    x = np.random.default_rng(1).random((16, 16, 3))
    assert ssim(x, x) == pytest.approx(1.0, abs=1e-12)
    assert psnr(x, x) == pytest.approx(120.0)  # the MSE floor of 1e-12 (no infinities in logs)


def test_ssim_of_constant_images_is_the_luminance_term():
    # Constant images have zero variance: SSIM = (2 mu_x mu_y + C1) / (mu_x^2 + mu_y^2 + C1), C1 = (0.01 L)^2.
    c1 = 0.01**2
    x, y = np.full((12, 12, 3), 0.5), np.full((12, 12, 3), 0.25)
    want = (2 * 0.5 * 0.25 + c1) / (0.5**2 + 0.25**2 + c1)
    assert ssim(x, y) == pytest.approx(want, abs=1e-9)


def _ssim_reference(x: np.ndarray, y: np.ndarray, win: int) -> float:
    """SSIM written out: Gaussian-weighted local means, variances and covariance (sigma 1.5, cut at 5 px =
    3.5 sigma, reflected borders), the SSIM map averaged over the pixels at least win // 2 from the border,
    then over the channels."""
    r = win // 2
    g = np.exp(-0.5 * (np.arange(-5, 6) / 1.5) ** 2)
    k = np.outer(g, g) / np.outer(g, g).sum()
    c1, c2 = 0.01**2, 0.03**2
    vals = []
    for ch in range(x.shape[-1]):
        a, b = x[..., ch], y[..., ch]
        f = lambda im: ndimage.correlate(im, k, mode="reflect")  # noqa: E731
        ma, mb = f(a), f(b)
        va, vb, cov = f(a * a) - ma**2, f(b * b) - mb**2, f(a * b) - ma * mb
        m = ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma**2 + mb**2 + c1) * (va + vb + c2))
        vals.append(m[r:-r, r:-r].mean())
    return float(np.mean(vals))


@pytest.mark.parametrize("shape,win", [((32, 40, 3), 11), ((9, 9, 3), 9), ((8, 10, 3), 7)])
def test_ssim_matches_the_written_out_formula(shape, win):
    rng = np.random.default_rng(2)
    x = rng.random(shape)
    y = np.clip(0.8 * x + 0.1 + rng.normal(0, 0.05, shape), 0, 1)
    assert ssim(y, x) == pytest.approx(_ssim_reference(y, x, win), abs=1e-6)
    assert 0.0 < ssim(y, x) < 1.0


def test_ssim_refuses_images_too_small_for_a_window():
    with pytest.raises(ValueError, match="3x3"):
        ssim(np.zeros((2, 5, 3)), np.zeros((2, 5, 3)))
