"""The numba kernel of the exports' median depth (depth.py states the math; tiles_numba.median_depth calls it):
per tile, the blend of tiles_kernels.py front to back, reading each pixel's depth on the planes of the Gaussians
where its running opacity crosses the central band of its final opacity. Forward only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nerfkit.models.splat.reference import ALPHA_MAX, ALPHA_MIN, T_MIN
from nerfkit.models.splat.tiles_geometry import (
    _OK,
    E_MIN,
    TILE,
    _entry,
    _row_start,
    _sharp_exp,
    _tile_box,
    _tile_cols,
    _tile_rows,
)


@njit(cache=True, inline="always")
def _plane_depth(planes, g, px, py):
    """z-depth where pixel (px, py)'s ray meets Gaussian g's density maximum (gaussians.depth_planes:
    planes[g] = (P00, P01, P02, P11, P12, P22, (P mu)_0, (P mu)_1, (P mu)_2, fx, fy, cx, cy, z_lo, z_hi) in
    OpenCV camera axes): with r = ((px - cx) / fx, (py - cy) / fy, 1), t* = r^T P mu / r^T P r, kept within
    [z_lo, z_hi]."""
    x = (px - planes[g, 11]) / planes[g, 9]
    y = (py - planes[g, 12]) / planes[g, 10]
    num = x * planes[g, 6] + y * planes[g, 7] + planes[g, 8]
    den = (planes[g, 0] * x * x + 2.0 * planes[g, 1] * x * y + 2.0 * planes[g, 2] * x + planes[g, 3] * y * y
           + 2.0 * planes[g, 4] * y + planes[g, 5])
    t = num / den if den > 0.0 else planes[g, 13]
    return min(planes[g, 14], max(planes[g, 13], t))


@njit(cache=True, inline="always")
def _band_step(planes, g, px, py, c0, c1, final, band, acc, wsum, y, x):
    """Add Gaussian g's share |[c0, c1] n [(1/2 - band) final, (1/2 + band) final]| of the band, read on its
    plane at pixel (px, py), to the tile's sums at (y, x); the pixel's depth once c1 passes the band, else NaN."""
    lo = (0.5 - band) * final
    if c1 < lo:
        return math.nan
    hi = (0.5 + band) * final
    tz = _plane_depth(planes, g, px, py)
    w = min(c1, hi) - max(c0, lo)
    if w > 0.0:
        acc[y, x] += w * tz
        wsum[y, x] += w
    if c1 < hi:
        return math.nan
    return acc[y, x] / wsum[y, x] if wsum[y, x] > 0.0 else tz


@njit(cache=True, nogil=True)
def median_tiles(gt, start, spans, planes, offsets, ids, width, height, t_final, band, out, first, stride):
    """Tiles first, first + stride, ...: at each pixel, blended front to back as _blend_tile does, the mean of
    its depth quantile function over the running opacities [(1/2 - band) A, (1/2 + band) A], A = 1 - t_final
    the pixel's final opacity: each Gaussian g weighs the share of that band its blend step [1 - T_before,
    1 - T_after] covers, and is read on its plane (_plane_depth). band = 0: the depth of the first Gaussian
    after which 1 - T reaches A / 2 (the median). 0 where the pixel has no opacity."""
    tiles_x = (width + TILE - 1) // TILE
    for t in range(first, offsets.size - 1, stride):
        x0, y0, nx, ny = _tile_box(t, tiles_x, width, height, TILE)
        trans, acc, wsum = np.ones((TILE, TILE)), np.zeros((TILE, TILE)), np.zeros((TILE, TILE))
        done = np.zeros((TILE, TILE), np.bool_)
        out[y0:y0 + ny, x0:x0 + nx] = 0.0
        done[:ny, :nx] = t_final[y0:y0 + ny, x0:x0 + nx] >= 1.0
        n_live = ny * nx - np.sum(done[:ny, :nx])
        for k in range(offsets[t + 1] - offsets[t]):
            if n_live == 0:
                break
            g = ids[offsets[t] + k]
            if gt[g, _OK] == 0.0:
                continue
            mx, my, a, b, c, o, _, _, q = _entry(gt, g)
            ys, ye, base = _tile_rows(gt, g, start, y0, ny)
            xa, ya, e0, r0, v0 = -1, -1, 0.0, 0.0, 0.0  # no scanline start yet
            for y in range(ys, ye + 1):
                xs, xe = _tile_cols(spans, base, y, x0, nx)
                if xs > xe:
                    continue
                dy = my - (y0 + y + 0.5)
                e0, r0, v0 = _row_start(gt, g, mx - (x0 + xs + 0.5), dy, xs, y, xa, ya, e0, r0, v0)
                xa, ya = xs, y
                e, r = e0, r0
                for x in range(xs, xe + 1):
                    if x > xs:
                        e *= r
                        r *= q
                    if done[y, x]:
                        continue
                    e = _sharp_exp(a, b, c, mx - (x0 + x + 0.5), dy, e)
                    if e < E_MIN:  # sigma > SIGMA_MAX
                        continue
                    alpha = min(ALPHA_MAX, o * e)
                    if alpha < ALPHA_MIN:
                        continue
                    next_t = trans[y, x] * (1.0 - alpha)
                    if next_t < T_MIN:  # the pixel ends here; its band lies before unless band = 1/2 (rounding)
                        done[y, x] = True
                        n_live -= 1
                        out[y0 + y, x0 + x] = acc[y, x] / wsum[y, x] if wsum[y, x] > 0.0 else 0.0
                        continue
                    depth = _band_step(planes, g, x0 + x + 0.5, y0 + y + 0.5, 1.0 - trans[y, x], 1.0 - next_t,
                                       1.0 - t_final[y0 + y, x0 + x], band, acc, wsum, y, x)
                    trans[y, x] = next_t
                    if not math.isnan(depth):
                        out[y0 + y, x0 + x] = depth
                        done[y, x] = True
                        n_live -= 1
        for y in range(ny):  # a pixel whose blend ended inside the band (rounding): the mean so far
            for x in range(nx):
                if not done[y, x] and wsum[y, x] > 0.0:
                    out[y0 + y, x0 + x] = acc[y, x] / wsum[y, x]
