"""Image quality metrics."""

from __future__ import annotations

import numpy as np


def mse_to_psnr(mse):
    """PSNR in dB of images in [0, 1]: -10 log10(MSE)."""
    return -10.0 * np.log10(np.maximum(mse, 1e-12))


def psnr(pred: np.ndarray, target: np.ndarray) -> float:
    return float(mse_to_psnr(np.mean((np.asarray(pred, np.float64) - np.asarray(target, np.float64)) ** 2)))


def ssim(pred: np.ndarray, target: np.ndarray) -> float:
    """SSIM of [H, W, 3] images in [0, 1]: 11x11 Gaussian window, sigma 1.5 (Wang et al. 2004),
    the variant reported by NeRF papers: the mean of the SSIM map over pixels at least 5 px from the
    border, then over channels. Images smaller than 11 px (the 1/8 scale of a small multiscale scene)
    average over pixels at least w // 2 from the border, w the largest odd size that fits (at least 3)."""
    side = min(np.shape(pred)[:2])
    if side < 3:
        raise ValueError(f"SSIM needs images of at least 3x3 pixels (got {np.shape(pred)[:2]})")
    win = 11 if side >= 11 else side - (1 - side % 2)
    from skimage.metrics import (
        structural_similarity,  # here: skimage costs 0.15 s of start-up
    )

    return float(structural_similarity(
        np.asarray(pred, np.float64), np.asarray(target, np.float64), data_range=1.0, channel_axis=-1,
        gaussian_weights=True, sigma=1.5, use_sample_covariance=False, win_size=win,
    ))
