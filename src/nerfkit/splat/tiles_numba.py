"""CPU tile rasteriser kernels (numba): binning, forward blend and backward pass.

Same image as reference.py (see its docstring for the blending rules), computed per 16 x 16
pixel tile over only the Gaussians whose 3-sigma ellipse can reach the tile:

1. Binning. The pixel rectangle of Gaussian k is its mean +- h, h_x = min(r_k + 1,
   3 sqrt(Sigma'_xx)) (and likewise for y; Sigma' = conic^{-1}): it holds the whole 3-sigma
   ellipse, which lies in the radius square. Live Gaussians (r_k > 0) are visited in
   depth order (stable argsort) and appended to every tile their rectangle touches, so each
   tile's list comes out already sorted by depth (a counting sort by tile, stable in depth:
   the same order as a sort on the (tile, depth) keys of the 3DGS code).
2. Forward, parallel over tiles: each pixel walks its tile's list front to back, stops
   early when T would drop below T_MIN, and records n_contrib = 1 + the list position of
   the last Gaussian it blended.
3. Backward, parallel over tiles, back to front from n_contrib - 1 with T recovered as
   T_k = T_{k+1} / (1 - alpha_k) from T_final, and R_k (the colour behind k per unit
   transmittance) as R_{k-1} = alpha_k c_k + (1 - alpha_k) R_k. For a loss L with
   G = dL/dcolour [C] and g_T = dL/dT_final + background . G at a pixel:

       dL/dc_k     += T_k alpha_k G
       dL/dalpha_k += T_k (c_k - R_k) . G - g_T T_final / (1 - alpha_k)
       alpha = o e^{-sigma} (unclamped):  dL/do += e^{-sigma} dL/dalpha,
       dL/dsigma = -alpha dL/dalpha,  dsigma/dm = (a d_x + b d_y, b d_x + c d_y),
       dsigma/d(a, b, c) = (d_x^2 / 2, d_x d_y, d_y^2 / 2);

   clamped alphas (o e^{-sigma} >= ALPHA_MAX) pass no gradient to o or sigma. Each tile sums
   into a per-tile buffer, then into one float64 buffer per thread (no races); the thread
   buffers are added at the end.

Arithmetic is float64 inside the kernels whatever the input dtype; outputs take the input
dtype. Kernels are compiled on first use and cached on disk (cache=True).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from nerfkit.splat.reference import ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN
from nerfkit.splat.project import SIGMA_CUTOFF

TILE = 16


@njit(cache=True)
def _tile_rects(means2d, conics, radii, width, height):
    """Tile rectangles [N, 4] (tx0, tx1, ty0, ty1), ends exclusive; empty for culled Gaussians."""
    n = means2d.shape[0]
    tiles_x = (width + TILE - 1) // TILE
    tiles_y = (height + TILE - 1) // TILE
    rects = np.zeros((n, 4), np.int32)
    for g in range(n):
        r = radii[g]
        if r <= 0:
            continue
        a, b, c = float(conics[g, 0]), float(conics[g, 1]), float(conics[g, 2])
        det = a * c - b * b
        hx = r + 1.0
        hy = r + 1.0
        if det > 0.0 and a > 0.0 and c > 0.0:
            hx = min(hx, SIGMA_CUTOFF * math.sqrt(c / det))
            hy = min(hy, SIGMA_CUTOFF * math.sqrt(a / det))
        mx, my = float(means2d[g, 0]), float(means2d[g, 1])
        if not (math.isfinite(mx) and math.isfinite(my)):
            continue
        # pixels j with |j + 0.5 - m| <= h, one pixel of slack for rounding
        j0 = max(0.0, math.floor(mx - hx - 0.5))
        j1 = min(width - 1.0, math.floor(mx + hx - 0.5) + 1.0)
        i0 = max(0.0, math.floor(my - hy - 0.5))
        i1 = min(height - 1.0, math.floor(my + hy - 0.5) + 1.0)
        if j0 > j1 or i0 > i1:
            continue
        rects[g, 0] = int(j0) // TILE
        rects[g, 1] = min(tiles_x, int(j1) // TILE + 1)
        rects[g, 2] = int(i0) // TILE
        rects[g, 3] = min(tiles_y, int(i1) // TILE + 1)
    return rects


@njit(cache=True)
def _bin(rects, order, n_tiles, tiles_x):
    """offsets [n_tiles + 1], ids [M]: tile t's Gaussians are ids[offsets[t]:offsets[t + 1]],
    in the order of `order` (depth order)."""
    counts = np.zeros(n_tiles + 1, np.int64)
    for g in order:
        for ty in range(rects[g, 2], rects[g, 3]):
            for tx in range(rects[g, 0], rects[g, 1]):
                counts[ty * tiles_x + tx + 1] += 1
    offsets = np.cumsum(counts)
    ids = np.empty(offsets[-1], np.int32)
    fill = offsets[:-1].copy()
    for g in order:
        for ty in range(rects[g, 2], rects[g, 3]):
            for tx in range(rects[g, 0], rects[g, 1]):
                t = ty * tiles_x + tx
                ids[fill[t]] = g
                fill[t] += 1
    return offsets, ids


def bin_gaussians(means2d, conics, depths, radii, width: int, height: int):
    """Tile lists of Gaussians, each sorted front to back: (offsets [n_tiles + 1] int64, ids [M] int32).

    Tiles are numbered row-major, tiles_x = ceil(width / 16) per row."""
    tiles_x = -(-width // TILE)
    tiles_y = -(-height // TILE)
    rects = _tile_rects(means2d, conics, radii, width, height)
    live = np.flatnonzero(radii > 0)
    order = live[np.argsort(depths[live], kind="stable")].astype(np.int32)
    return _bin(rects, order, tiles_x * tiles_y, tiles_x)


@njit(cache=True, inline="always")
def _pack(means2d, conics, opacities, colors, ids, start, n, geo, col):
    """Copy a tile's Gaussians into contiguous float64 arrays geo [n, 6] (mx, my, a, b, c, o), col [n, C]."""
    for k in range(n):
        g = ids[start + k]
        geo[k, 0] = means2d[g, 0]
        geo[k, 1] = means2d[g, 1]
        geo[k, 2] = conics[g, 0]
        geo[k, 3] = conics[g, 1]
        geo[k, 4] = conics[g, 2]
        geo[k, 5] = opacities[g]
        for ch in range(colors.shape[1]):
            col[k, ch] = colors[g, ch]


@njit(parallel=True, cache=True)
def _forward(means2d, conics, colors, opacities, background, offsets, ids, width, height, image, t_final, n_contrib):
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in prange(offsets.size - 1):
        start = offsets[t]
        n = offsets[t + 1] - start
        geo = np.empty((n, 6))
        col = np.empty((n, n_ch))
        _pack(means2d, conics, opacities, colors, ids, start, n, geo, col)
        acc = np.empty(n_ch)
        x0 = (t % tiles_x) * TILE
        y0 = (t // tiles_x) * TILE
        for y in range(y0, min(y0 + TILE, height)):
            py = y + 0.5
            for x in range(x0, min(x0 + TILE, width)):
                px = x + 0.5
                acc[:] = 0.0
                trans = 1.0
                last = 0
                for k in range(n):
                    dx = geo[k, 0] - px
                    dy = geo[k, 1] - py
                    sigma = 0.5 * (geo[k, 2] * dx * dx + geo[k, 4] * dy * dy) + geo[k, 3] * dx * dy
                    if sigma < 0.0 or sigma > SIGMA_MAX:
                        continue
                    alpha = min(ALPHA_MAX, geo[k, 5] * math.exp(-sigma))
                    if alpha < ALPHA_MIN:
                        continue
                    next_t = trans * (1.0 - alpha)
                    if next_t < T_MIN:
                        break
                    w = alpha * trans
                    for ch in range(n_ch):
                        acc[ch] += w * col[k, ch]
                    trans = next_t
                    last = k + 1
                for ch in range(n_ch):
                    image[y, x, ch] = acc[ch] + trans * background[ch]
                t_final[y, x] = trans
                n_contrib[y, x] = last


@njit(parallel=True, cache=True)
def _backward(means2d, conics, colors, opacities, background, offsets, ids, width, height, t_final, n_contrib,
              grad_image, grad_t, out):
    """Per-thread gradient sums out [threads, N, 6 + C]: (m_x, m_y, a, b, c, o, colours)."""
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in prange(offsets.size - 1):
        start = offsets[t]
        n = offsets[t + 1] - start
        geo = np.empty((n, 6))
        col = np.empty((n, n_ch))
        _pack(means2d, conics, opacities, colors, ids, start, n, geo, col)
        acc = np.zeros((n, 6 + n_ch))
        rec = np.empty(n_ch)
        x0 = (t % tiles_x) * TILE
        y0 = (t // tiles_x) * TILE
        for y in range(y0, min(y0 + TILE, height)):
            py = y + 0.5
            for x in range(x0, min(x0 + TILE, width)):
                px = x + 0.5
                t_end = float(t_final[y, x])
                g_t = float(grad_t[y, x])
                for ch in range(n_ch):
                    g_t += background[ch] * grad_image[y, x, ch]
                rec[:] = 0.0
                trans = t_end
                for k in range(n_contrib[y, x] - 1, -1, -1):
                    dx = geo[k, 0] - px
                    dy = geo[k, 1] - py
                    a, b, c = geo[k, 2], geo[k, 3], geo[k, 4]
                    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
                    if sigma < 0.0 or sigma > SIGMA_MAX:
                        continue
                    e = math.exp(-sigma)
                    raw = geo[k, 5] * e
                    alpha = min(ALPHA_MAX, raw)
                    if alpha < ALPHA_MIN:
                        continue
                    one_minus = 1.0 - alpha
                    trans = trans / one_minus
                    w = alpha * trans
                    d_alpha = 0.0
                    for ch in range(n_ch):
                        gc = grad_image[y, x, ch]
                        acc[k, 6 + ch] += w * gc
                        d_alpha += (col[k, ch] - rec[ch]) * gc
                        rec[ch] = alpha * col[k, ch] + one_minus * rec[ch]
                    d_alpha = d_alpha * trans - g_t * t_end / one_minus
                    if raw < ALPHA_MAX:
                        acc[k, 5] += e * d_alpha
                        d_sigma = -alpha * d_alpha
                        acc[k, 0] += d_sigma * (a * dx + b * dy)
                        acc[k, 1] += d_sigma * (b * dx + c * dy)
                        acc[k, 2] += d_sigma * 0.5 * dx * dx
                        acc[k, 3] += d_sigma * dx * dy
                        acc[k, 4] += d_sigma * 0.5 * dy * dy
        tid = numba.get_thread_id()
        for k in range(n):
            g = ids[start + k]
            for q in range(6 + n_ch):
                out[tid, g, q] += acc[k, q]


def forward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int):
    """Render (numpy in, numpy out): image [H, W, C], t_final [H, W], n_contrib [H, W] int32.

    Inputs as in reference.rasterize_reference; outputs in the dtype of `colors`."""
    dtype = np.result_type(colors.dtype, np.float32)
    offsets, ids = bin_gaussians(means2d, conics, depths, radii, width, height)
    image = np.empty((height, width, colors.shape[1]), dtype)
    t_final = np.empty((height, width), dtype)
    n_contrib = np.empty((height, width), np.int32)
    with numba.parallel_chunksize(1):
        _forward(means2d, conics, colors, opacities, background, offsets, ids, width, height, image, t_final,
                 n_contrib)
    return image, t_final, n_contrib


def backward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int, t_final,
             n_contrib, grad_image, grad_t):
    """Gradients of a loss L given G = dL/dimage [H, W, C] and dL/dt_final [H, W].

    Returns dL/d(means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], background [C]),
    each in its input's dtype."""
    offsets, ids = bin_gaussians(means2d, conics, depths, radii, width, height)
    n, n_ch = colors.shape
    out = np.zeros((numba.get_num_threads(), n, 6 + n_ch))
    with numba.parallel_chunksize(1):
        _backward(means2d, conics, colors, opacities, background, offsets, ids, width, height, t_final, n_contrib,
                  grad_image, grad_t, out)
    total = out.sum(0) if out.shape[0] > 1 else out[0]
    g_bg = np.einsum("hw,hwc->c", t_final.astype(np.float64), grad_image.astype(np.float64))
    return (total[:, 0:2].astype(means2d.dtype), total[:, 2:5].astype(conics.dtype),
            total[:, 6:].astype(colors.dtype), total[:, 5].astype(opacities.dtype), g_bg.astype(background.dtype))
