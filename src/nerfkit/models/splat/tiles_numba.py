"""CPU tile rasteriser kernels (numba): binning, forward blend and backward pass.

Same image as reference.py (see its docstring for the blending rules), computed per 16 x 16
pixel tile over only the Gaussians that can reach the tile. A Gaussian of opacity o passes
the alpha test only inside its ellipse d^T Q d <= s(o) = 2 min(SIGMA_MAX, log(o / ALPHA_MIN))
(Q the conic; o < ALPHA_MIN: nowhere), which lies inside its 3-sigma ellipse and so inside
its radius square. Conics must be positive definite (project.py's are: Sigma' >= 0.3 I);
Gaussians with others are skipped.

1. Binning. Gaussian k's pixel box is its mean +- h, h_x = min(r_k + 1, sqrt(s(o) Sigma'_xx))
   (likewise y; Sigma' = Q^{-1}), one pixel of slack for rounding. Live Gaussians (r_k > 0)
   are visited in depth order (stable argsort) and appended to every tile their box
   touches, so each tile's list comes out already sorted by depth (a counting sort by tile,
   stable in depth: the order a sort on (tile, depth) keys gives, as in the 3DGS code).
2. Forward, tiles spread over worker threads (the kernels release the GIL). Within a tile,
   the Gaussians are taken front to back and each visits only the pixels of its ellipse,
   scanline by scanline (the rows within sqrt(s Sigma'_yy), in each row the d_x between the
   roots of d^T Q d = s; one pixel of slack, and the exact per-pixel tests still decide;
   e^{-sigma} is advanced along the row by two products per pixel, see _row_exp). Per pixel: T,
   the colour sum, a done flag (set when T would drop below T_MIN) and n_contrib = 1 + the list
   position of the last Gaussian blended. The tile stops when all its pixels are done.
3. Backward, tiles spread over worker threads: the same scan back to front from the tile's largest
   n_contrib, each pixel taking part for k < n_contrib, with T recovered as
   T_k = T_{k+1} / (1 - alpha_k) from T_final, and R_k (the colour behind k per unit
   transmittance) as R_{k-1} = alpha_k c_k + (1 - alpha_k) R_k. For a loss L with
   G = dL/dcolour [C] and g_T = dL/dT_final + background . G at a pixel:

       dL/dc_k     += T_k alpha_k G
       dL/dalpha_k += T_k (c_k - R_k) . G - g_T T_final / (1 - alpha_k)
       alpha = o e^{-sigma} (unclamped):  dL/do += e^{-sigma} dL/dalpha,
       dL/dsigma = -alpha dL/dalpha,  dsigma/dm = (a d_x + b d_y, b d_x + c d_y),
       dsigma/d(a, b, c) = (d_x^2 / 2, d_x d_y, d_y^2 / 2);

   clamped alphas (o e^{-sigma} >= ALPHA_MAX) pass no gradient to o or sigma. A Gaussian's
   sums over a tile's pixels go into one float64 buffer per worker (no races); the worker
   buffers are added at the end.

The kernels take float64 arrays (the host functions convert: one compiled variant, and the
float32 and float64 paths are the same code); outputs take the input dtype. Kernels are
compiled on first use and cached on disk (cache=True).
"""

from __future__ import annotations

import math
import os
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit

from nerfkit.models.splat.reference import ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN

TILE = 16
THREADS: int | None = None  # worker threads; None: every CPU in os.sched_getaffinity
CHUNKS_PER_WORKER = 8
_POOL: ThreadPoolExecutor | None = None


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


def bin_gaussians(means2d, conics, opacities, depths, radii, width: int, height: int):
    """Tile lists of Gaussians, each sorted front to back: (offsets [n_tiles + 1] int64, ids [M] int32).

    Tiles are numbered row-major, tiles_x = ceil(width / 16) per row."""
    tiles_x = -(-width // TILE)
    tiles_y = -(-height // TILE)
    rects = _tile_rects(means2d, conics, opacities, radii, width, height)
    live = np.flatnonzero(radii > 0)
    order = live[np.argsort(depths[live], kind="stable")].astype(np.int32)
    return _bin(rects, order, tiles_x * tiles_y, tiles_x)


_LOG_ALPHA_MIN = math.log(ALPHA_MIN)
_A_RECUR = 25.0  # conic a (px^-2) up to which e^{-sigma} is advanced by products along rows


@njit(cache=True, inline="always")
def _span(o):
    """Bound on d^T Q d = 2 sigma where Gaussian of opacity o can pass the alpha test, with rounding slack:
    sigma <= SIGMA_MAX and o e^{-sigma} >= ALPHA_MIN, i.e. sigma <= log(o / ALPHA_MIN). Negative: never."""
    if not o >= ALPHA_MIN:
        return -1.0
    return 2.0 * min(SIGMA_MAX, math.log(o) - _LOG_ALPHA_MIN) * (1.0 + 1e-6) + 1e-9


@njit(cache=True, inline="always")
def _rows(my, a, det, span, y0, ny):
    """Tile rows [ys, ye] (relative to y0) that the ellipse d^T Q d <= span may reach."""
    sy = math.sqrt(span * a / det)  # Sigma'_yy = a / det
    return max(0, int(math.floor(my - sy - 0.5)) - y0), min(ny - 1, int(math.floor(my + sy - 0.5)) + 1 - y0)


@njit(cache=True, inline="always")
def _cols(mx, dy, a, b, c, span, x0, nx):
    """Tile columns [xs, xe] (relative to x0) of the ellipse's span in the row at offset dy = m_y - p_y."""
    disc = b * b * dy * dy - a * (c * dy * dy - span)
    if disc < 0.0:
        return 0, -1
    sq = math.sqrt(disc)
    hi = (-b * dy + sq) / a  # d_x = m_x - p_x, so p_x spans [m_x - hi, m_x - lo]
    lo = (-b * dy - sq) / a
    return max(0, int(math.floor(mx - hi - 0.5)) - x0), min(nx - 1, int(math.floor(mx - lo - 0.5)) + 1 - x0)


@njit(cache=True, inline="always")
def _row_exp(dx, dy, a, b, c):
    """(e^{-sigma}, e^{-(sigma' - sigma)}) at the first pixel of a scanline, sigma' the next pixel's.

    Along a row, d_x drops by 1 per pixel and sigma(d_x - 1) - sigma(d_x) = -(a d_x + b d_y) + a/2,
    whose own step is +a: e^{-sigma} advances as e <- e r, r <- r e^{-a}, two products per pixel
    instead of an exp (relative drift ~1e-15 over a tile row; both passes use the same sequence).
    With Sigma' >= 0.3 I (project.py's dilation), a <= 1 / 0.3 and |log r| stays below ~10 over the
    span and its slack; sharper conics (a > _A_RECUR) take an exp per pixel instead (no overflow)."""
    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
    return math.exp(-sigma), math.exp(a * dx + b * dy - 0.5 * a)


@njit(cache=True)
def _tile_rects(means2d, conics, opacities, radii, width, height):
    """Tile rectangles [N, 4] (tx0, tx1, ty0, ty1), ends exclusive, of the pixel boxes that hold each
    Gaussian's ellipse d^T Q d <= _span(o) (at most its radius square); empty when it cannot show."""
    n = means2d.shape[0]
    tiles_x = (width + TILE - 1) // TILE
    tiles_y = (height + TILE - 1) // TILE
    rects = np.zeros((n, 4), np.int32)
    for g in range(n):
        a, b, c = float(conics[g, 0]), float(conics[g, 1]), float(conics[g, 2])
        mx, my = float(means2d[g, 0]), float(means2d[g, 1])
        det = a * c - b * b
        span = _span(float(opacities[g]))
        if radii[g] <= 0 or not (a > 0.0 and det > 0.0 and span > 0.0 and math.isfinite(mx) and math.isfinite(my)):
            continue
        hx = min(radii[g] + 1.0, math.sqrt(span * c / det))  # Sigma'_xx = c / det
        hy = min(radii[g] + 1.0, math.sqrt(span * a / det))
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


@njit(cache=True, nogil=True)
def _forward(means2d, conics, colors, opacities, background, offsets, ids, width, height, image, t_final, n_contrib,
             first, stride):
    """Tiles first, first + stride, ... (one worker's share)."""
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in range(first, offsets.size - 1, stride):
        start = offsets[t]
        x0 = (t % tiles_x) * TILE
        y0 = (t // tiles_x) * TILE
        nx = min(TILE, width - x0)
        ny = min(TILE, height - y0)
        trans = np.ones((TILE, TILE))
        done = np.zeros((TILE, TILE), np.bool_)
        last = np.zeros((TILE, TILE), np.int32)
        acc = np.zeros((TILE, TILE, n_ch))
        col = np.empty(n_ch)
        n_live = nx * ny
        for k in range(offsets[t + 1] - start):
            g = ids[start + k]
            mx, my = float(means2d[g, 0]), float(means2d[g, 1])
            a, b, c = float(conics[g, 0]), float(conics[g, 1]), float(conics[g, 2])
            o = float(opacities[g])
            det = a * c - b * b
            span = _span(o)
            if not (a > 0.0 and det > 0.0 and span > 0.0):
                continue
            for ch in range(n_ch):
                col[ch] = colors[g, ch]
            q = math.exp(-a)
            ys, ye = _rows(my, a, det, span, y0, ny)
            for y in range(ys, ye + 1):
                dy = my - (y0 + y + 0.5)
                xs, xe = _cols(mx, dy, a, b, c, span, x0, nx)
                e, r = _row_exp(mx - (x0 + xs + 0.5), dy, a, b, c)
                for x in range(xs, xe + 1):
                    if x > xs:
                        e *= r
                        r *= q
                    if done[y, x]:
                        continue
                    dx = mx - (x0 + x + 0.5)
                    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
                    if sigma < 0.0 or sigma > SIGMA_MAX:
                        continue
                    if a > _A_RECUR:
                        e = math.exp(-sigma)
                    alpha = min(ALPHA_MAX, o * e)
                    if alpha < ALPHA_MIN:
                        continue
                    next_t = trans[y, x] * (1.0 - alpha)
                    if next_t < T_MIN:
                        done[y, x] = True
                        n_live -= 1
                        continue
                    w = alpha * trans[y, x]
                    for ch in range(n_ch):
                        acc[y, x, ch] += w * col[ch]
                    trans[y, x] = next_t
                    last[y, x] = k + 1
            if n_live == 0:
                break
        for y in range(ny):
            for x in range(nx):
                for ch in range(n_ch):
                    image[y0 + y, x0 + x, ch] = acc[y, x, ch] + trans[y, x] * background[ch]
                t_final[y0 + y, x0 + x] = trans[y, x]
                n_contrib[y0 + y, x0 + x] = last[y, x]


@njit(cache=True, nogil=True)
def _backward(means2d, conics, colors, opacities, background, offsets, ids, width, height, t_final, n_contrib,
              grad_image, grad_t, out, first, stride):
    """Gradient sums over tiles first, first + stride, ... into out [N, 6 + C]: (m_x, m_y, a, b, c, o, colours)."""
    n_ch = colors.shape[1]
    tiles_x = (width + TILE - 1) // TILE
    for t in range(first, offsets.size - 1, stride):
        start = offsets[t]
        x0 = (t % tiles_x) * TILE
        y0 = (t // tiles_x) * TILE
        nx = min(TILE, width - x0)
        ny = min(TILE, height - y0)
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
        g_col = np.empty(n_ch)
        col = np.empty(n_ch)
        for k in range(n_blend.max() - 1, -1, -1):
            g = ids[start + k]
            mx, my = means2d[g, 0], means2d[g, 1]
            a, b, c = conics[g, 0], conics[g, 1], conics[g, 2]
            o = opacities[g]
            det = a * c - b * b
            span = _span(o)
            if not (a > 0.0 and det > 0.0 and span > 0.0):
                continue
            for ch in range(n_ch):
                col[ch] = colors[g, ch]
            g_col[:] = 0.0
            g_mx = g_my = g_a = g_b = g_c = g_o = 0.0
            q = math.exp(-a)
            ys, ye = _rows(my, a, det, span, y0, ny)
            for y in range(ys, ye + 1):
                dy = my - (y0 + y + 0.5)
                xs, xe = _cols(mx, dy, a, b, c, span, x0, nx)
                e, r = _row_exp(mx - (x0 + xs + 0.5), dy, a, b, c)
                for x in range(xs, xe + 1):
                    if x > xs:
                        e *= r
                        r *= q
                    if k >= n_blend[y, x]:
                        continue
                    dx = mx - (x0 + x + 0.5)
                    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
                    if sigma < 0.0 or sigma > SIGMA_MAX:
                        continue
                    if a > _A_RECUR:
                        e = math.exp(-sigma)
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
            out[g, 0] += g_mx
            out[g, 1] += g_my
            out[g, 2] += 0.5 * g_a
            out[g, 3] += g_b
            out[g, 4] += 0.5 * g_c
            out[g, 5] += g_o
            for ch in range(n_ch):
                out[g, 6 + ch] += g_col[ch]


def _f64(*arrays):
    """C-contiguous float64 copies (one compiled kernel variant serves every input dtype)."""
    return [np.ascontiguousarray(a, np.float64) for a in arrays]


def worker_count(threads: int | None = None) -> int:
    """Worker threads a call with `threads` uses (None: THREADS, else every CPU this process may use)."""
    return max(1, threads or THREADS or len(os.sched_getaffinity(0)))


def _run(kernel, threads: int | None, args_of) -> None:
    """Run kernel(*args_of(w), first, stride) over all tiles on n worker threads (the kernels release
    the GIL). The tiles are cut into CHUNKS_PER_WORKER x n interleaved chunks (chunk i: tiles i,
    i + stride, ...: each spread over the image, so of similar cost), handed out as workers free
    up, which keeps a worker that the OS delays (a shared machine) from holding up the rest;
    w (0 .. n - 1) names a per-worker buffer no other running chunk uses."""
    n = worker_count(threads)
    if n == 1:
        kernel(*args_of(0), 0, 1)
        return
    global _POOL
    if _POOL is None or _POOL._max_workers < n:
        _POOL = ThreadPoolExecutor(n, thread_name_prefix="splat")
    free = queue.SimpleQueue()
    for w in range(n):
        free.put(w)
    stride = CHUNKS_PER_WORKER * n

    def chunk(first):
        w = free.get()
        try:
            kernel(*args_of(w), first, stride)
        finally:
            free.put(w)

    for f in [_POOL.submit(chunk, i) for i in range(stride)]:
        f.result()


def forward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
            threads: int | None = None):
    """Render (numpy in, numpy out): image [H, W, C], t_final [H, W], n_contrib [H, W] int32.

    Inputs as in reference.rasterize_reference; float outputs in the dtype of `colors`.
    threads: worker threads (default THREADS, or all CPUs this process may use)."""
    dtype = np.result_type(colors.dtype, np.float32)
    means2d, conics, colors, opacities, background = _f64(means2d, conics, colors, opacities, background)
    radii = np.ascontiguousarray(radii, np.int32)
    offsets, ids = bin_gaussians(means2d, conics, opacities, depths, radii, width, height)
    image = np.empty((height, width, colors.shape[1]))
    t_final = np.empty((height, width))
    n_contrib = np.empty((height, width), np.int32)
    _run(_forward, threads, lambda w: (means2d, conics, colors, opacities, background, offsets, ids, width, height,
                                       image, t_final, n_contrib))
    return image.astype(dtype, copy=False), t_final.astype(dtype, copy=False), n_contrib


def backward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int, t_final,
             n_contrib, grad_image, grad_t, threads: int | None = None):
    """Gradients of a loss L given G = dL/dimage [H, W, C] and dL/dt_final [H, W].

    Returns dL/d(means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], background [C]),
    each in its input's dtype."""
    dtypes = [a.dtype for a in (means2d, conics, colors, opacities, background)]
    means2d, conics, colors, opacities, background, t_final, grad_image, grad_t = _f64(
        means2d, conics, colors, opacities, background, t_final, grad_image, grad_t)
    radii = np.ascontiguousarray(radii, np.int32)
    n_contrib = np.ascontiguousarray(n_contrib, np.int32)
    offsets, ids = bin_gaussians(means2d, conics, opacities, depths, radii, width, height)
    n, n_ch = colors.shape
    workers = worker_count(threads)
    out = np.zeros((workers, n, 6 + n_ch))
    _run(_backward, workers, lambda w: (means2d, conics, colors, opacities, background, offsets, ids, width, height,
                                        t_final, n_contrib, grad_image, grad_t, out[w]))
    total = out.sum(0) if out.shape[0] > 1 else out[0]
    g_bg = np.einsum("hw,hwc->c", t_final, grad_image)
    grads = (total[:, 0:2], total[:, 2:5], total[:, 6:], total[:, 5], g_bg)
    return tuple(g.astype(dt) for g, dt in zip(grads, dtypes))
