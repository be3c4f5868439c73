"""The numba kernels of the CPU tile rasteriser (tiles_numba.py calls them; its docstring states the
binning, the blend and the gradients they compute). Where each Gaussian reaches (its constants, the spans of its
rows, the binning, the walk of e^{-sigma} from one scanline to the next) is tiles_geometry.py's.

    forward_tiles           per tile: _blend_tile (front to back), _store_tile
    frame_tiles             the same for a view only looked at: _blend_tile, _store_frame
    backward_tiles          per tile: _load_tile, _unblend_tile (back to front)

depth_kernels.py holds the exports' depth kernel (median_tiles), built on the same helpers.

The per-tile helpers are inlined (inline="always") and take a whole tile: a helper called once per
Gaussian with the scanline loop inside cost the backward pass 2-4 % (measured); these cost nothing.
Kernels take float64 arrays (images may be float32) and are compiled on first use and cached on disk
(cache=True).
"""

from __future__ import annotations

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
def _blend_tile(ids, first, count, gt, start, spans, colors, x0, y0, nx, ny, trans, done, last, acc, track):
    """Blend the tile's list ids[first:first + count] front to back into its pixels (gt, start, spans:
    tiles_numba.Bins.rows): at each pixel of a Gaussian's ellipse not yet done, acc += alpha T c, T *= 1 -
    alpha, if track last = k + 1 (k its list position); a pixel whose T would drop below T_MIN is done instead.
    Stops when every pixel is done. Three and four channels (colour, colour and depth) are written out, not
    looped over (with the 3-sigma cut read on e^{-sigma}: a seventh of the forward pass at 800 px, measured)."""
    n_ch = colors.shape[1]
    col = np.zeros(max(n_ch, 4))
    n_live = nx * ny
    for k in range(count):
        g = ids[first + k]
        if gt[g, _OK] == 0.0:
            continue
        mx, my, a, b, c, o, _, _, q = _entry(gt, g)
        for ch in range(n_ch):
            col[ch] = colors[g, ch]
        c0, c1, c2, c3 = col[0], col[1], col[2], col[3]
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
                t_k = trans[y, x]
                next_t = t_k * (1.0 - alpha)
                if next_t < T_MIN:
                    done[y, x] = True
                    n_live -= 1
                    continue
                w = alpha * t_k
                if n_ch == 3 or n_ch == 4:
                    acc[y, x, 0] += w * c0
                    acc[y, x, 1] += w * c1
                    acc[y, x, 2] += w * c2
                    if n_ch == 4:
                        acc[y, x, 3] += w * c3
                else:
                    for ch in range(n_ch):
                        acc[y, x, ch] += w * col[ch]
                trans[y, x] = next_t
                if track:
                    last[y, x] = k + 1
        if n_live == 0:
            break


@njit(cache=True, inline="always")
def _store_tile(acc, trans, last, background, n_ch, x0, y0, nx, ny, image, t_final, n_contrib):
    """Write a blended tile out: image = acc + T background, t_final = T, n_contrib = last."""
    for y in range(ny):
        for x in range(nx):
            for ch in range(n_ch):
                image[y0 + y, x0 + x, ch] = acc[y, x, ch] + trans[y, x] * background[ch]
            t_final[y0 + y, x0 + x] = trans[y, x]
            n_contrib[y0 + y, x0 + x] = last[y, x]


@njit(cache=True, nogil=True)
def forward_tiles(gt, start, spans, colors, background, offsets, ids, width, height, image, t_final, n_contrib, first,
                  stride):
    """Tiles first, first + stride, ... (one worker's share): each blended (_blend_tile), then written out.
    gt: gaussian_table; start, spans: row_spans'."""
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in range(first, offsets.size - 1, stride):
        x0, y0, nx, ny = _tile_box(t, tiles_x, width, height, TILE)
        trans = np.ones((TILE, TILE))
        done = np.zeros((TILE, TILE), np.bool_)
        last = np.zeros((TILE, TILE), np.int32)
        acc = np.zeros((TILE, TILE, n_ch))
        _blend_tile(ids, offsets[t], offsets[t + 1] - offsets[t], gt, start, spans, colors, x0, y0, nx, ny, trans,
                    done, last, acc, True)
        _store_tile(acc, trans, last, background, n_ch, x0, y0, nx, ny, image, t_final, n_contrib)


@njit(cache=True, inline="always")
def _store_frame(acc, trans, background, n_ch, x0, y0, nx, ny, rgb, extra, alpha):
    """Write a blended tile out as a view: rgb = acc + T background in the first three channels, clipped to
    [0, 1]; extra = the same unclipped in the others (a depth channel); alpha = 1 - T."""
    for y in range(ny):
        for x in range(nx):
            t = trans[y, x]
            for ch in range(3):
                rgb[y0 + y, x0 + x, ch] = min(1.0, max(0.0, acc[y, x, ch] + t * background[ch]))
            for ch in range(3, n_ch):
                extra[y0 + y, x0 + x, ch - 3] = acc[y, x, ch] + t * background[ch]
            alpha[y0 + y, x0 + x] = 1.0 - t


@njit(cache=True, nogil=True)
def frame_tiles(gt, start, spans, colors, background, offsets, ids, width, height, tile, rgb, extra, alpha, first,
                stride):
    """forward_tiles for a view that is only looked at (no gradients follow): tiles of tile x tile pixels, and
    the outputs _store_frame writes in place of the image, T_final and n_contrib."""
    n_ch = colors.shape[1]
    tiles_x = (width + tile - 1) // tile
    untracked = np.empty((1, 1), np.int32)  # no contributor counts
    for t in range(first, offsets.size - 1, stride):
        x0, y0, nx, ny = _tile_box(t, tiles_x, width, height, tile)
        trans = np.ones((tile, tile))
        done = np.zeros((tile, tile), np.bool_)
        acc = np.zeros((tile, tile, n_ch))
        _blend_tile(ids, offsets[t], offsets[t + 1] - offsets[t], gt, start, spans, colors, x0, y0, nx, ny, trans,
                    done, untracked, acc, False)
        _store_frame(acc, trans, background, n_ch, x0, y0, nx, ny, rgb, extra, alpha)


@njit(cache=True, inline="always")
def _load_tile(t_final, n_contrib, grad_image, grad_t, background, n_ch, x0, y0, nx, ny):
    """A tile's state for the backward scan: (T [16, 16], from T_final; g_end = (dL/dT_final + background . G)
    T_final; G [16, 16, C]; n_contrib; R [16, 16, C] = 0, the colour behind)."""
    trans = np.empty((TILE, TILE))  # T_k, recovered back to front from T_final
    g_end = np.empty((TILE, TILE))  # (dL/dT_final + background . G) T_final
    g_img = np.empty((TILE, TILE, n_ch))  # G
    n_blend = np.zeros((TILE, TILE), np.int64)  # n_contrib
    rec = np.zeros((TILE, TILE, n_ch))  # R_k
    for y in range(ny):
        for x in range(nx):
            trans[y, x] = t_final[y0 + y, x0 + x]
            n_blend[y, x] = n_contrib[y0 + y, x0 + x]
            g_t = grad_t[y0 + y, x0 + x]
            for ch in range(n_ch):
                g_img[y, x, ch] = grad_image[y0 + y, x0 + x, ch]
                g_t += background[ch] * g_img[y, x, ch]
            g_end[y, x] = g_t * trans[y, x]
    return trans, g_end, g_img, n_blend, rec


@njit(cache=True, inline="always")
def _add_grads(out, g, g_mx, g_my, g_a, g_b, g_c, g_o, g_col):
    """out[g] += the sums (dL/dm_x, dL/dm_y, dL/da, dL/db, dL/dc, dL/do, dL/dcolour); g_a, g_c are twice dL/da,
    dL/dc."""
    out[g, 0] += g_mx
    out[g, 1] += g_my
    out[g, 2] += 0.5 * g_a
    out[g, 3] += g_b
    out[g, 4] += 0.5 * g_c
    out[g, 5] += g_o
    for ch in range(g_col.size):
        out[g, 6 + ch] += g_col[ch]


@njit(cache=True, inline="always")
def _unblend_tile(ids, first, gt, start, spans, colors, n_ch, x0, y0, nx, ny, trans, g_end, g_img, n_blend, rec,
                  out):
    """Take the tile's Gaussians back off its pixels, back to front from its largest n_contrib (each pixel for
    k < n_contrib), with T_k = T_{k+1} / (1 - alpha_k) and R_{k-1} = alpha_k c_k + (1 - alpha_k) R_k, adding
    each Gaussian's gradient sums over the tile to out[g] (tiles_numba.py, step 3)."""
    col, g_col = np.empty(n_ch), np.empty(n_ch)
    for k in range(n_blend.max() - 1, -1, -1):
        g = ids[first + k]
        if gt[g, _OK] == 0.0:
            continue
        mx, my, a, b, c, o, _, _, q = _entry(gt, g)
        for ch in range(n_ch):
            col[ch], g_col[ch] = colors[g, ch], 0.0
        g_mx = g_my = g_a = g_b = g_c = g_o = 0.0
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
                if k >= n_blend[y, x]:
                    continue
                dx = mx - (x0 + x + 0.5)
                e = _sharp_exp(a, b, c, dx, dy, e)
                if e < E_MIN:  # sigma > SIGMA_MAX
                    continue
                raw = o * e
                alpha = min(ALPHA_MAX, raw)
                if alpha < ALPHA_MIN:
                    continue
                inv = 1.0 / (1.0 - alpha)
                t_k = trans[y, x] * inv
                trans[y, x] = t_k
                w = alpha * t_k
                d_alpha = 0.0
                for ch in range(n_ch):
                    gc = g_img[y, x, ch]
                    behind = rec[y, x, ch]
                    g_col[ch] += w * gc
                    d_alpha += (col[ch] - behind) * gc
                    rec[y, x, ch] = behind + alpha * (col[ch] - behind)  # alpha c + (1 - alpha) R
                if raw < ALPHA_MAX:
                    d_alpha = d_alpha * t_k - g_end[y, x] * inv
                    g_o += e * d_alpha
                    d_sigma = -alpha * d_alpha
                    g_mx += d_sigma * (a * dx + b * dy)
                    g_my += d_sigma * (b * dx + c * dy)
                    g_a += d_sigma * dx * dx
                    g_b += d_sigma * dx * dy
                    g_c += d_sigma * dy * dy
        _add_grads(out, g, g_mx, g_my, g_a, g_b, g_c, g_o, g_col)


@njit(cache=True, nogil=True)
def backward_tiles(gt, start, spans, colors, background, offsets, ids, width, height, t_final, n_contrib, grad_image,
                   grad_t, out, first, stride):
    """Gradient sums over tiles first, first + stride, ... into out [N, 6 + C]: (m_x, m_y, a, b, c, o, colours);
    each tile's state loaded (_load_tile), then its Gaussians taken back off (_unblend_tile)."""
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in range(first, offsets.size - 1, stride):
        x0, y0, nx, ny = _tile_box(t, tiles_x, width, height, TILE)
        trans, g_end, g_img, n_blend, rec = _load_tile(t_final, n_contrib, grad_image, grad_t, background, n_ch,
                                                       x0, y0, nx, ny)
        _unblend_tile(ids, offsets[t], gt, start, spans, colors, n_ch, x0, y0, nx, ny, trans, g_end, g_img, n_blend,
                      rec, out)
