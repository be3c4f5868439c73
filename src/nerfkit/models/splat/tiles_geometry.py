"""Where each Gaussian reaches, for the CPU tile rasteriser's kernels (tiles_kernels.py, depth_kernels.py):

    gaussian_table          once a pass, per Gaussian: mean, conic, opacity, the alpha test's bound, its image
                            rows, and the ratios e^{-a}, e^{-b}, e^{-c} that scanlines advance e^{-sigma} by
    row_spans               once a pass, per Gaussian and image row: the columns of its ellipse's span
    tile_rects, bin_tiles   binning: each Gaussian's tile rectangle, the per-tile lists in depth order
    _span, _rows, _cols     the alpha test's ellipse d^T Q d <= s(o), its rows and each row's columns
    _tile_rows, _tile_cols  a Gaussian's rows in a tile and each one's columns, read off row_spans
    _row_start              e^{-sigma} and its ratios at a scanline's first pixel, walked from the last one's

Helpers are inlined into the kernels (inline="always"); kernels are compiled on first use and cached on disk.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nerfkit.models.splat.reference import ALPHA_MIN, SIGMA_MAX

TILE = 16


@njit(cache=True, nogil=True)
def bin_tiles(rects, order, n_tiles, tiles_x):
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


@njit(cache=True, nogil=True)
def radix_order(keys, values):
    """values [L] (int32) sorted by keys [L] (uint32), ascending, ties in their given order: a stable
    least-significant-digit radix sort, four passes of 8 bits carrying the keys along. A fifth of numpy's sort
    of 50k uint64 (key, index) pairs on this machine, which is what it replaces."""
    n = keys.size
    k_src, k_dst = keys.copy(), np.empty_like(keys)
    v_src, v_dst = values.copy(), np.empty_like(values)
    for shift in range(0, 32, 8):
        start = np.zeros(257, np.int64)
        for i in range(n):
            start[((k_src[i] >> shift) & 255) + 1] += 1
        for b in range(256):
            start[b + 1] += start[b]
        for i in range(n):
            b = (k_src[i] >> shift) & 255
            k_dst[start[b]] = k_src[i]
            v_dst[start[b]] = v_src[i]
            start[b] += 1
        k_src, k_dst = k_dst, k_src
        v_src, v_dst = v_dst, v_src
    return v_src


_LOG_ALPHA_MIN = math.log(ALPHA_MIN)
E_MIN = math.exp(-SIGMA_MAX)  # the 3-sigma cut sigma <= SIGMA_MAX, read on e^{-sigma}
_A_RECUR = 25.0  # conic a (px^-2) up to which e^{-sigma} is advanced by products (else an exp a pixel)
WALK = 4  # a scanline start at most this many steps (rows down + columns across) from the last is walked to

# gaussian_table's columns
_MX, _MY, _A, _B, _C, _O, _DET, _SPAN, _OK, _INV_A, _EA, _EB, _EC, _Y0, _NROWS, _TAME = range(16)


@njit(cache=True, inline="always")
def _span(o):
    """Bound on d^T Q d = 2 sigma where Gaussian of opacity o can pass the alpha test, with rounding slack:
    sigma <= SIGMA_MAX and o e^{-sigma} >= ALPHA_MIN, i.e. sigma <= log(o / ALPHA_MIN). Negative: never."""
    if not o >= ALPHA_MIN:
        return -1.0
    return 2.0 * min(SIGMA_MAX, math.log(o) - _LOG_ALPHA_MIN) * (1.0 + 1e-6) + 1e-9


@njit(cache=True, inline="always")
def _shows(a, det, span, mx, my):
    """Whether a Gaussian can show anywhere: its conic positive definite (a > 0, det Q > 0), its opacity able to
    pass the alpha test (span > 0, _span) and its mean finite."""
    return a > 0.0 and det > 0.0 and span > 0.0 and math.isfinite(mx) and math.isfinite(my)


@njit(cache=True, nogil=True)
def gaussian_table(means2d, conics, opacities, radii, height):
    """[N, 16] float64, a row per Gaussian: m_x, m_y, the conic Q = [[a, b], [b, c]], opacity o, det Q, the alpha
    test's bound _span(o), ok (1: Q positive definite and span > 0; 0: it shows nowhere), and where ok 1 / a, the
    ratios e^{-a}, e^{-b}, e^{-c} of _row_start, the image rows its ellipse reaches (_rows): the first and how
    many (0 where not ok or culled, radii <= 0), and tame (1: a, |b|, c <= _A_RECUR, so _row_start may walk).
    Once a pass, rather than once per tile a Gaussian lands in."""
    n = means2d.shape[0]
    gt = np.zeros((n, 16))
    for g in range(n):
        a, b, c = float(conics[g, 0]), float(conics[g, 1]), float(conics[g, 2])
        o = float(opacities[g])
        det = a * c - b * b
        span = _span(o)
        mx, my = float(means2d[g, 0]), float(means2d[g, 1])
        gt[g, _MX], gt[g, _MY] = mx, my
        gt[g, _A], gt[g, _B], gt[g, _C], gt[g, _O], gt[g, _DET], gt[g, _SPAN] = a, b, c, o, det, span
        if _shows(a, det, span, mx, my):
            gt[g, _OK], gt[g, _INV_A] = 1.0, 1.0 / a
            gt[g, _EA], gt[g, _EB], gt[g, _EC] = math.exp(-a), math.exp(-b), math.exp(-c)
            gt[g, _TAME] = 1.0 if max(a, abs(b), c) <= _A_RECUR else 0.0
            ys, ye = _rows(my, a, det, span, 0, height)
            if radii[g] > 0 and ye >= ys:
                gt[g, _Y0], gt[g, _NROWS] = ys, ye - ys + 1
    return gt


@njit(cache=True, nogil=True)
def span_starts(gt):
    """[N + 1] int64: start[g] = the rows of Gaussians before g (gaussian_table's counts), row_spans' offsets."""
    start = np.zeros(gt.shape[0] + 1, np.int64)
    for g in range(gt.shape[0]):
        start[g + 1] = start[g] + int(gt[g, _NROWS])
    return start


@njit(cache=True, nogil=True)
def row_spans(gt, start, width, spans, first, stride):
    """Gaussians first, first + stride, ...: spans[start[g] + i] = (xs, xe), the image columns (_cols) of Gaussian
    g's ellipse in image row gt[g, _Y0] + i, i < gt[g, _NROWS] (xs > xe: none); start = the running sum of
    _NROWS. Each row once a pass: the tiles it crosses clip it (_tile_cols) instead of solving it again."""
    for g in range(first, gt.shape[0], stride):
        mx, my, a, b, _, _, det, span, _ = _entry(gt, g)
        y0 = int(gt[g, _Y0])
        for i in range(start[g + 1] - start[g]):
            spans[start[g] + i, 0], spans[start[g] + i, 1] = _cols(mx, my - (y0 + i + 0.5), a, b, det, gt[g, _INV_A],
                                                                 span, 0, width)


@njit(cache=True, inline="always")
def _tile_rows(gt, g, start, y0, ny):
    """(ys, ye, base): the tile rows [ys, ye] (relative to y0) that Gaussian g's ellipse reaches; spans[base + y]
    holds tile row y's image columns."""
    gy = int(gt[g, _Y0])
    return max(0, gy - y0), min(ny - 1, gy + int(gt[g, _NROWS]) - 1 - y0), start[g] - gy + y0


@njit(cache=True, inline="always")
def _tile_cols(spans, base, y, x0, nx):
    """Tile columns [xs, xe] (relative to x0) of the span in tile row y (xs > xe: none in this tile)."""
    return max(0, spans[base + y, 0] - x0), min(nx - 1, spans[base + y, 1] - x0)


@njit(cache=True, inline="always")
def _rows(my, a, det, span, y0, ny):
    """Tile rows [ys, ye] (relative to y0) whose pixel centres p_y lie within the ellipse d^T Q d <= span's rows,
    |p_y - m_y| <= sqrt(span Sigma'_yy), Sigma'_yy = a / det. No pixel of slack: _span's own (a millionth of
    the bound) is far above the rounding here, so every pixel that can pass the alpha test is inside."""
    sy = math.sqrt(span * a / det)
    return max(0, int(math.ceil(my - sy - 0.5)) - y0), min(ny - 1, int(math.floor(my + sy - 0.5)) - y0)


@njit(cache=True, inline="always")
def _cols(mx, dy, a, b, det, inv_a, span, x0, nx):
    """Tile columns [xs, xe] (relative to x0) of the ellipse's span in the row at offset dy = m_y - p_y: the pixel
    centres between the roots of a d_x^2 + 2 b d_x d_y + c d_y^2 = span (no pixel of slack, as _rows)."""
    disc = a * span - det * dy * dy  # (b d_y)^2 - a (c d_y^2 - span)
    if disc < 0.0:
        return 0, -1
    sq = math.sqrt(disc)
    hi = (-b * dy + sq) * inv_a  # d_x = m_x - p_x, so p_x spans [m_x - hi, m_x - lo]
    lo = (-b * dy - sq) * inv_a
    return max(0, int(math.ceil(mx - hi - 0.5)) - x0), min(nx - 1, int(math.floor(mx - lo - 0.5)) - x0)


@njit(cache=True, inline="always")
def _row_start(gt, g, dx, dy, xs, y, xa, ya, e, r, v):
    """(e, r, v) at pixel (xs, y) of a tile, d = (dx, dy) = m - p there: e = e^{-sigma(d)}, and r = e(x + 1) / e(x),
    v = e(y + 1) / e(y) its ratios to the next pixel along the row and down the column:

        sigma = (a d_x^2 + c d_y^2) / 2 + b d_x d_y,  r = e^{a d_x + b d_y - a/2},  v = e^{b d_x + c d_y - c/2}.

    Walked by products from (e, r, v) at the Gaussian's previous scanline start (xa, ya) in the tile when
    (y - ya) + |xs - xa| <= WALK: a step down is e <- e v, r <- r e^{-b}, v <- v e^{-c}; one to the right
    e <- e r, v <- v e^{-b}, r <- r e^{-a}; one to the left r <- r e^{a}, e <- e / r, v <- v e^{b}. Exact (three
    exps) when there is none (ya < 0), it is further, or the conic is not tame (gaussian_table: a, |b|, c <=
    _A_RECUR; project.py's are, with Sigma' >= 0.3 I). Row starts lie in or beside the ellipse, so for a tame
    conic every ratio and value walked through stays within e^{+-200}, far from overflow and underflow. Each
    product adds an ulp of relative error (~1e-15 over a tile).
    Along the row, e <- e r, r <- r e^{-a} (two products a pixel). Forward and backward walk the same sequence."""
    if ya < 0 or gt[g, _TAME] == 0.0 or (y - ya) + abs(xs - xa) > WALK:
        a, b, c = gt[g, _A], gt[g, _B], gt[g, _C]
        return (math.exp(-(0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy)), math.exp(a * dx + b * dy - 0.5 * a),
                math.exp(b * dx + c * dy - 0.5 * c))
    p, s = gt[g, _EB], gt[g, _EC]
    for _ in range(y - ya):
        e *= v
        r *= p
        v *= s
    if xs >= xa:
        q = gt[g, _EA]
        for _ in range(xs - xa):
            e *= r
            v *= p
            r *= q
    else:
        iq, ip = 1.0 / gt[g, _EA], 1.0 / p
        for _ in range(xa - xs):
            r *= iq
            e /= r
            v *= ip
    return e, r, v


@njit(cache=True, nogil=True)
def tile_rects(means2d, conics, opacities, radii, width, height, tile):
    """Tile rectangles [N, 4] (tx0, tx1, ty0, ty1), ends exclusive, of the pixel boxes that hold each
    Gaussian's ellipse d^T Q d <= _span(o) (at most its radius square), for tiles of tile x tile pixels (tile a
    power of two: pixels to tiles by a shift, a fifth of this pass against a division); empty when it cannot
    show."""
    n = means2d.shape[0]
    shift = 0
    while (1 << shift) < tile:
        shift += 1
    tiles_x = (width + tile - 1) // tile
    tiles_y = (height + tile - 1) // tile
    rects = np.zeros((n, 4), np.int32)
    for g in range(n):
        a, b, c = float(conics[g, 0]), float(conics[g, 1]), float(conics[g, 2])
        mx, my = float(means2d[g, 0]), float(means2d[g, 1])
        det = a * c - b * b
        span = _span(float(opacities[g]))
        if radii[g] <= 0 or not _shows(a, det, span, mx, my):
            continue
        hx = min(radii[g] + 1.0, math.sqrt(span * c / det))  # Sigma'_xx = c / det
        hy = min(radii[g] + 1.0, math.sqrt(span * a / det))
        # pixels j with |j + 0.5 - m| <= h (as _rows, no pixel of slack)
        j0 = max(0.0, math.ceil(mx - hx - 0.5))
        j1 = min(width - 1.0, math.floor(mx + hx - 0.5))
        i0 = max(0.0, math.ceil(my - hy - 0.5))
        i1 = min(height - 1.0, math.floor(my + hy - 0.5))
        if j0 > j1 or i0 > i1:
            continue
        rects[g, 0] = int(j0) >> shift
        rects[g, 1] = min(tiles_x, (int(j1) >> shift) + 1)
        rects[g, 2] = int(i0) >> shift
        rects[g, 3] = min(tiles_y, (int(i1) >> shift) + 1)
    return rects


@njit(cache=True, inline="always")
def _tile_box(t, tiles_x, width, height, tile):
    """(x0, y0, nx, ny): the first pixel column and row of tile t (row-major, tiles_x tiles of tile x tile pixels
    per row) and its width and height in pixels (edge tiles are cut by the image)."""
    x0 = (t % tiles_x) * tile
    y0 = (t // tiles_x) * tile
    return x0, y0, min(tile, width - x0), min(tile, height - y0)


@njit(cache=True, inline="always")
def _entry(gt, g):
    """(m_x, m_y, a, b, c, o, det, span, e^{-a}) of Gaussian g's row of gaussian_table."""
    return gt[g, _MX], gt[g, _MY], gt[g, _A], gt[g, _B], gt[g, _C], gt[g, _O], gt[g, _DET], gt[g, _SPAN], gt[g, _EA]


@njit(cache=True, inline="always")
def _sharp_exp(a, b, c, dx, dy, e):
    """e^{-sigma} at d = (dx, dy) for a conic too sharp for products along the row (a > _A_RECUR: |log r| could
    reach overflow over a tile), else e as walked; sigma < 0 (rounding, at most) reads as the 3-sigma cut's 0."""
    if a <= _A_RECUR:
        return e
    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
    return math.exp(-sigma) if sigma >= 0.0 else 0.0
