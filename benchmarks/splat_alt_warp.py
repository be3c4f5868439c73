"""Benchmark candidate: the tile rasteriser's blend written for NVIDIA Warp's CPU backend.

Not used by `rasterize` (benchmarks/splat_raster.py compares it with the numba kernels).
The Warp version has the GPU layout of the 3DGS code: one kernel thread per pixel walks its
tile's depth-sorted list (front to back; back to front in the backward pass with T recovered
by division, gradients summed with atomic adds). The tile lists come from the numba binning
(tiles_numba.bin_gaussians), so only the blend differs. float32 throughout (Warp's `float`);
same rules and outputs as tiles_numba.forward / backward. Needs `pip install warp-lang`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from nerfkit.models.splat.reference import ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN
from nerfkit.models.splat.tiles_numba import TILE, bin_gaussians

wp.config.quiet = True
_AMAX, _AMIN, _SMAX, _TMIN = (wp.constant(float(v)) for v in (ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN))
_TILE = wp.constant(TILE)


@wp.func
def _sigma(means2d: wp.array2d(dtype=float), conics: wp.array2d(dtype=float), g: int, px: float, py: float):
    dx = means2d[g, 0] - px
    dy = means2d[g, 1] - py
    return 0.5 * (conics[g, 0] * dx * dx + conics[g, 2] * dy * dy) + conics[g, 1] * dx * dy


@wp.kernel
def _forward(means2d: wp.array2d(dtype=float), conics: wp.array2d(dtype=float), colors: wp.array2d(dtype=float),
             opacities: wp.array(dtype=float), background: wp.array(dtype=float), offsets: wp.array(dtype=int),
             ids: wp.array(dtype=int), tiles_x: int, image: wp.array3d(dtype=float), t_final: wp.array2d(dtype=float),
             n_contrib: wp.array2d(dtype=int)):
    i, j = wp.tid()
    t = (i // _TILE) * tiles_x + j // _TILE
    start = offsets[t]
    px = float(j) + 0.5
    py = float(i) + 0.5
    n_ch = colors.shape[1]
    for ch in range(n_ch):
        image[i, j, ch] = 0.0
    trans = float(1.0)
    last = int(0)
    for k in range(offsets[t + 1] - start):
        g = ids[start + k]
        sigma = _sigma(means2d, conics, g, px, py)
        if sigma < 0.0 or sigma > _SMAX:
            continue
        alpha = wp.min(_AMAX, opacities[g] * wp.exp(-sigma))
        if alpha < _AMIN:
            continue
        next_t = trans * (1.0 - alpha)
        if next_t < _TMIN:
            break
        for ch in range(n_ch):
            image[i, j, ch] = image[i, j, ch] + alpha * trans * colors[g, ch]
        trans = next_t
        last = k + 1
    for ch in range(n_ch):
        image[i, j, ch] = image[i, j, ch] + trans * background[ch]
    t_final[i, j] = trans
    n_contrib[i, j] = last


@wp.kernel
def _backward(means2d: wp.array2d(dtype=float), conics: wp.array2d(dtype=float), colors: wp.array2d(dtype=float),
              opacities: wp.array(dtype=float), background: wp.array(dtype=float), offsets: wp.array(dtype=int),
              ids: wp.array(dtype=int), tiles_x: int, t_final: wp.array2d(dtype=float),
              n_contrib: wp.array2d(dtype=int),
              grad_image: wp.array3d(dtype=float), grad_t: wp.array2d(dtype=float), rec: wp.array3d(dtype=float),
              out: wp.array2d(dtype=float)):
    i, j = wp.tid()
    t = (i // _TILE) * tiles_x + j // _TILE
    start = offsets[t]
    px = float(j) + 0.5
    py = float(i) + 0.5
    n_ch = colors.shape[1]
    t_end = t_final[i, j]
    g_t = grad_t[i, j]
    for ch in range(n_ch):
        g_t = g_t + background[ch] * grad_image[i, j, ch]
        rec[i, j, ch] = 0.0
    trans = t_end
    n = n_contrib[i, j]
    for step in range(n):
        k = n - 1 - step
        g = ids[start + k]
        dx = means2d[g, 0] - px
        dy = means2d[g, 1] - py
        a = conics[g, 0]
        b = conics[g, 1]
        c = conics[g, 2]
        sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
        if sigma < 0.0 or sigma > _SMAX:
            continue
        e = wp.exp(-sigma)
        raw = opacities[g] * e
        alpha = wp.min(_AMAX, raw)
        if alpha < _AMIN:
            continue
        one_minus = 1.0 - alpha
        trans = trans / one_minus
        d_alpha = float(0.0)
        for ch in range(n_ch):
            gc = grad_image[i, j, ch]
            wp.atomic_add(out, g, 6 + ch, alpha * trans * gc)
            d_alpha = d_alpha + (colors[g, ch] - rec[i, j, ch]) * gc
            rec[i, j, ch] = alpha * colors[g, ch] + one_minus * rec[i, j, ch]
        d_alpha = d_alpha * trans - g_t * t_end / one_minus
        if raw < _AMAX:
            wp.atomic_add(out, g, 5, e * d_alpha)
            d_sigma = -alpha * d_alpha
            wp.atomic_add(out, g, 0, d_sigma * (a * dx + b * dy))
            wp.atomic_add(out, g, 1, d_sigma * (b * dx + c * dy))
            wp.atomic_add(out, g, 2, d_sigma * 0.5 * dx * dx)
            wp.atomic_add(out, g, 3, d_sigma * dx * dy)
            wp.atomic_add(out, g, 4, d_sigma * 0.5 * dy * dy)


def _wp(x, dtype=np.float32):
    return wp.array(np.ascontiguousarray(x, dtype), device="cpu")


def _tiles(means2d, conics, opacities, depths, radii, width, height):
    offsets, ids = bin_gaussians(*(np.asarray(a, np.float64) for a in (means2d, conics, opacities)),
                                 np.asarray(depths), np.asarray(radii, np.int32), width, height)
    return _wp(offsets, np.int32), _wp(ids, np.int32)


def forward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int):
    """As tiles_numba.forward (float32 outputs)."""
    offsets, ids = _tiles(means2d, conics, opacities, depths, radii, width, height)
    image = wp.empty((height, width, colors.shape[1]), dtype=float, device="cpu")
    t_final = wp.empty((height, width), dtype=float, device="cpu")
    n_contrib = wp.empty((height, width), dtype=int, device="cpu")
    wp.launch(_forward, dim=(height, width), device="cpu",
              inputs=[_wp(means2d), _wp(conics), _wp(colors), _wp(opacities), _wp(background), offsets, ids,
                      -(-width // TILE), image, t_final, n_contrib])
    return image.numpy(), t_final.numpy(), n_contrib.numpy()


def backward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int, t_final,
             n_contrib, grad_image, grad_t):
    """As tiles_numba.backward (float32 gradients)."""
    offsets, ids = _tiles(means2d, conics, opacities, depths, radii, width, height)
    n, n_ch = colors.shape
    out = wp.zeros((n, 6 + n_ch), dtype=float, device="cpu")
    rec = wp.empty((height, width, n_ch), dtype=float, device="cpu")
    wp.launch(_backward, dim=(height, width), device="cpu",
              inputs=[_wp(means2d), _wp(conics), _wp(colors), _wp(opacities), _wp(background), offsets, ids,
                      -(-width // TILE), _wp(t_final), _wp(n_contrib, np.int32), _wp(grad_image), _wp(grad_t), rec,
                      out])
    total = out.numpy()
    g_bg = np.einsum("hw,hwc->c", np.asarray(t_final, np.float64), np.asarray(grad_image, np.float64))
    return total[:, 0:2], total[:, 2:5], total[:, 6:], total[:, 5], g_bg.astype(np.float32)
