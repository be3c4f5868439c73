"""The CPU tile rasteriser's passes, on the host: binning, the forward blend and the backward pass, each
running tiles_kernels.py's numba kernels (and tiles_geometry.py's) over the tiles in parallel threads.

Same image as reference.py (see its docstring for the blending rules), computed per 16 x 16
pixel tile over only the Gaussians that can reach the tile. A Gaussian of opacity o passes
the alpha test only inside its ellipse d^T Q d <= s(o) = 2 min(SIGMA_MAX, log(o / ALPHA_MIN))
(Q the conic; o < ALPHA_MIN: nowhere), which lies inside its 3-sigma ellipse and so inside
its radius square. Conics must be positive definite (project.py's are: Sigma' >= 0.3 I);
Gaussians with others are skipped.

1. Binning. Gaussian k's pixel box is the pixels whose centres lie within its mean +- h,
   h_x = min(r_k + 1, sqrt(s(o) Sigma'_xx)) (likewise y; Sigma' = Q^{-1}); s(o) carries a
   millionth of slack for rounding. Live Gaussians (r_k > 0)
   are visited in depth order (stable argsort) and appended to every tile their box
   touches, so each tile's list comes out already sorted by depth (a counting sort by tile,
   stable in depth: the order a sort on (tile, depth) keys gives, as in the 3DGS code). The
   kernels see the live Gaussians renumbered in local_order (grouped by the tile their mean
   falls in; bin_local), so that a tile's list reads nearby rows of the per-Gaussian arrays.
2. Forward, tiles spread over worker threads (the kernels release the GIL). Within a tile,
   the Gaussians are taken front to back and each visits only the pixels of its ellipse,
   scanline by scanline (the rows within sqrt(s Sigma'_yy), in each row the d_x between the
   roots of d^T Q d = s; the exact per-pixel tests still decide; e^{-sigma} is advanced along
   the row by two products per pixel, and from one scanline's start to the next by a few,
   see _row_start; per-Gaussian constants come from gaussian_table, once a pass). Per pixel: T,
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

The kernels (tiles_kernels.py, tiles_geometry.py) take float64 inputs (the host functions here convert:
the float32 and float64 paths are the same code) and write the forward's image and T in the colours'
dtype (a compiled variant per output dtype, no copy after). Kernels are compiled on first use and cached
on disk (cache=True).
"""

from __future__ import annotations

import queue
import threading
from typing import NamedTuple

import numpy as np

from nerfkit.core.threads import cpu_count, pool
from nerfkit.models.splat.tiles_geometry import (
    TILE,
    bin_tiles,
    gaussian_table,
    radix_order,
    row_spans,
    span_starts,
    tile_rects,
)
from nerfkit.models.splat.tiles_kernels import backward_tiles, forward_tiles, frame_tiles
from nerfkit.models.splat.depth_kernels import median_tiles

THREADS: int | None = None  # worker threads; None: every CPU this process may use (core/threads.py)
CHUNKS_PER_WORKER = 8
FRAME_TILE = 64  # frame()'s tiles, in pixels (a power of two)


def depth_order(depths, live) -> np.ndarray:
    """Indices [L] int32 of the Gaussians `live` (indices) sorted by depth, ties in index order: what a
    stable argsort gives. For float32 depths (training's), a stable radix sort (tiles_geometry.radix_order)
    of the depths' bits made order-preserving as unsigned integers: several times faster than numpy's stable
    argsort, which other dtypes take."""
    if depths.dtype != np.float32:
        return live[np.argsort(depths[live], kind="stable")].astype(np.int32)
    bits = np.ascontiguousarray(depths[live] + np.float32(0.0)).view(np.uint32)  # -0 + 0 = +0: one zero
    bits = bits ^ np.where(bits >> 31 == 1, np.uint32(0xFFFFFFFF), np.uint32(0x80000000))  # negatives reversed
    return radix_order(bits, np.ascontiguousarray(live, np.int32))


def table_spans(table, width: int, threads: int | None = None):
    """(start, spans): each Gaussian's image rows with their columns (tiles_geometry.span_starts and row_spans, on
    the worker threads) of a gaussian_table, what the blend kernels read instead of solving every scanline once per
    tile it crosses."""
    start = span_starts(table)
    spans = np.empty((start[-1], 2), np.int16 if width < 2**15 else np.int32)  # half the bytes to read
    _run(row_spans, threads, lambda w: (table, start, width, spans))
    return start, spans


def local_order(means2d, depths, radii, width: int, height: int, tile: int) -> tuple[np.ndarray, np.ndarray]:
    """(perm [L], order [L]) int32 for the L live Gaussians (radii > 0): perm groups them by the tile their mean
    falls in (row-major, tiles of tile x tile pixels; a mean off the image counts in the nearest tile), each group
    in depth order; order is depth_order's sequence (ties by index, the blend's order) as positions in perm. The
    kernels then read a Gaussian's table row, spans and colours from a few runs of nearby rows per tile instead of
    from all over the arrays: the per-entry cache misses are most of the blend's time (lego at 800 px, 64-px tiles:
    a quarter off the blend, measured)."""
    by_depth = depth_order(depths, np.flatnonzero(radii > 0))
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    centre = np.nan_to_num(np.take(means2d, by_depth, axis=0)) // tile
    key = np.clip(centre[:, 1], 0, tiles_y - 1) * tiles_x + np.clip(centre[:, 0], 0, tiles_x - 1)
    by_tile = np.argsort(key.astype(np.int16 if tiles_x * tiles_y < 2**15 else np.int32), kind="stable")  # radix
    order = np.empty(len(by_tile), np.int32)
    order[by_tile] = np.arange(len(by_tile), dtype=np.int32)
    return by_depth[by_tile], order


class Bins(NamedTuple):
    """A pass's geometry (bin_local). The kernels number the live Gaussians in local_order: their index k is
    Gaussian perm[k] (the table's row k, the colours taken in that order), and ids lists those indices."""

    width: int
    height: int
    tile: int
    perm: np.ndarray  # [L] int32
    offsets: np.ndarray  # [n_tiles + 1] int64: tile t's list is ids[offsets[t]:offsets[t + 1]]
    ids: np.ndarray  # [M] int32, front to back within each tile
    rows: tuple  # (table, start, spans) of the Gaussians in perm's order

    def local(self, values: np.ndarray) -> np.ndarray:
        """values [N, ...] per Gaussian, in the kernels' order [L, ...]."""
        return np.take(values, self.perm, axis=0)

    def scattered(self, values: np.ndarray, n: int) -> np.ndarray:
        """values [L + 1, ...] in the kernels' order with a zero row at L, per Gaussian [n, ...] (zero where not
        live)."""
        where = np.full(n, len(self.perm), np.int64)
        where[self.perm] = np.arange(len(self.perm))
        return np.take(values, where, axis=0)


def bin_local(means2d, conics, opacities, depths, radii, width: int, height: int, threads: int | None,
              tile: int = TILE) -> Bins:
    """The Bins of a pass (float64 inputs): local_order, the tile lists and the rows' spans. With more than one
    worker thread (the kernels release the GIL), one builds the gaussian_table while this thread orders the
    Gaussians, then the spans of its rows while this one bins."""
    workers = pool(worker_count(threads)) if worker_count(threads) > 1 else None
    table = workers.submit(gaussian_table, means2d, conics, opacities, radii, height) if workers else None
    perm, order = local_order(means2d, depths, radii, width, height, tile)
    table = np.take(table.result() if workers else gaussian_table(means2d, conics, opacities, radii, height), perm,
                    axis=0)
    spans = workers.submit(table_spans, table, width, 1) if workers else None
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    rects = tile_rects(*(np.take(a, perm, axis=0) for a in (means2d, conics, opacities, radii)), width, height, tile)
    offsets, ids = bin_tiles(rects, order, tiles_x * tiles_y, tiles_x)
    spans = spans.result() if workers else table_spans(table, width, 1)
    return Bins(width, height, tile, perm, offsets, ids, (table, *spans))


def bin_gaussians(means2d, conics, opacities, depths, radii, width: int, height: int, tile: int = TILE):
    """Tile lists of Gaussians, each sorted front to back: (offsets [n_tiles + 1] int64, ids [M] int32), ids the
    Gaussians' own indices: what the benchmarks count and time. The passes bin with bin_local (the same lists,
    numbered in local_order).

    Tiles of tile x tile pixels are numbered row-major, tiles_x = ceil(width / tile) per row."""
    tiles_x = -(-width // tile)
    tiles_y = -(-height // tile)
    rects = tile_rects(means2d, conics, opacities, radii, width, height, tile)
    order = depth_order(depths, np.flatnonzero(radii > 0))
    return bin_tiles(rects, order, tiles_x * tiles_y, tiles_x)


class _KeptBins:
    """The tile lists of the last KEEP forward passes, by token, so that a backward pass on the same inputs
    (rasterize_numba.py passes the token from its forward to its backward) need not bin again. A token
    not found (evicted, or none) means binning again: the lists are a function of the inputs either way."""

    KEEP = 8

    def __init__(self):
        self._lock = threading.Lock()
        self._bins: dict[int, tuple] = {}
        self._next = 1

    def put(self, bins) -> int:
        with self._lock:
            token = self._next
            self._next = self._next % 2_000_000_000 + 1
            self._bins[token] = bins
            while len(self._bins) > self.KEEP:
                del self._bins[next(iter(self._bins))]
            return token

    def take(self, token: int):
        with self._lock:
            return self._bins.pop(int(token), None)


KEPT_BINS = _KeptBins()


class _Buffers:
    """Zeroed float64 buffers by shape, reused from call to call: the backward's per-worker gradient sums are
    megabytes, and a fresh allocation of that size is fresh pages from the OS, zeroed by the kernel on first
    touch and unmapped again when freed (page faults and TLB shootdowns: about a tenth of a backward pass at
    200 px with 50k Gaussians, in a perf profile). A buffer is handed to one caller at a time."""

    def __init__(self):
        self._lock = threading.Lock()
        self._free: dict[tuple, list] = {}

    def take(self, shape: tuple) -> np.ndarray:
        with self._lock:
            spare = self._free.get(shape)
            buf = spare.pop() if spare else None
        if buf is None:
            return np.zeros(shape)
        buf.fill(0.0)
        return buf

    def give(self, buf: np.ndarray) -> None:
        with self._lock:
            self._free = {k: v for k, v in self._free.items() if k == buf.shape}  # keep one shape's buffers
            self._free.setdefault(buf.shape, []).append(buf)


_SUMS = _Buffers()


def _f64(*arrays):
    """C-contiguous float64 copies (one compiled kernel variant serves every input dtype)."""
    return [np.ascontiguousarray(a, np.float64) for a in arrays]


def worker_count(threads: int | None = None) -> int:
    """Worker threads a call with `threads` uses (None: THREADS, else every CPU this process may use)."""
    return max(1, threads or THREADS or cpu_count())


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
    workers = pool(n)
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

    for f in [workers.submit(chunk, i) for i in range(stride)]:
        f.result()


def forward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
            threads: int | None = None, keep_bins: bool = False):
    """Render (numpy in, numpy out): image [H, W, C], t_final [H, W], n_contrib [H, W] int32.

    Inputs as in reference.rasterize_reference; float outputs in the dtype of `colors`.
    threads: worker threads (default THREADS, or all CPUs this process may use).
    keep_bins: also return a token (int) under which the tile lists are kept for backward(bins=token)."""
    dtype = np.result_type(colors.dtype, np.float32)
    means2d, conics, colors, opacities, background = _f64(means2d, conics, colors, opacities, background)
    radii = np.ascontiguousarray(radii, np.int32)
    bins = bin_local(means2d, conics, opacities, depths, radii, width, height, threads)
    token = KEPT_BINS.put(bins) if keep_bins else None
    image = np.empty((height, width, colors.shape[1]), dtype)  # the kernel writes the output dtype: no copy
    t_final = np.empty((height, width), dtype)
    n_contrib = np.empty((height, width), np.int32)
    local = bins.local(colors)
    _run(forward_tiles, threads, lambda w: (*bins.rows, local, background, bins.offsets, bins.ids, width, height,
                                            image, t_final, n_contrib))
    out = image, t_final, n_contrib
    return out + (token,) if keep_bins else out


def frame(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
          threads: int | None = None, tile: int = FRAME_TILE):
    """Render a view that is only looked at (numpy in, numpy out; no backward follows): rgb [H, W, 3] clipped to
    [0, 1], extra [H, W, C - 3] (the channels after the third, unclipped: a depth channel), alpha [H, W] = 1 -
    T_final, all float32; the pixels of forward()'s image. Tiles of tile x tile pixels (FRAME_TILE: fewer tile
    entries at a viewer's sizes; the training passes keep 16, where a backward tile of 32 outgrows L1), the
    Gaussians taken in local_order."""
    means2d, conics, colors, opacities, background = _f64(means2d, conics, colors, opacities, background)
    bins = bin_local(means2d, conics, opacities, depths, np.ascontiguousarray(radii, np.int32), width, height,
                     threads, tile)
    rgb = np.empty((height, width, 3), np.float32)
    extra = np.empty((height, width, colors.shape[1] - 3), np.float32)
    alpha = np.empty((height, width), np.float32)
    local = bins.local(colors)
    _run(frame_tiles, threads, lambda w: (*bins.rows, local, background, bins.offsets, bins.ids, width, height, tile,
                                          rgb, extra, alpha))
    return rgb, extra, alpha


def backward(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int, t_final,
             n_contrib, grad_image, grad_t, threads: int | None = None, bins: int | None = None):
    """Gradients of a loss L given G = dL/dimage [H, W, C] and dL/dt_final [H, W].

    Returns dL/d(means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], background [C]),
    each in its input's dtype. bins: the token of forward(keep_bins=True) on these inputs (its tile lists are
    used, and dropped), or None to bin again."""
    dtypes = [a.dtype for a in (means2d, conics, colors, opacities, background)]
    means2d, conics, colors, opacities, background, t_final, grad_image, grad_t = _f64(
        means2d, conics, colors, opacities, background, t_final, grad_image, grad_t)
    radii = np.ascontiguousarray(radii, np.int32)
    n_contrib = np.ascontiguousarray(n_contrib, np.int32)
    kept = KEPT_BINS.take(bins) if bins is not None else None
    if kept is None or (kept.width, kept.height, kept.tile) != (width, height, TILE):
        kept = bin_local(means2d, conics, opacities, depths, radii, width, height, threads)
    n, n_ch = colors.shape
    workers = worker_count(threads)
    out = _SUMS.take((workers, n + 1, 6 + n_ch))  # rows in the kernels' order; those from len(perm) on stay 0
    local = kept.local(colors)
    try:
        _run(backward_tiles, workers, lambda w: (*kept.rows, local, background, kept.offsets, kept.ids, width, height,
                                                 t_final, n_contrib, grad_image, grad_t, out[w]))
        total = out[0]
        for w in range(1, workers):
            total += out[w]
        total = kept.scattered(total, n)  # a copy: the buffer goes back
        g_bg = np.einsum("hw,hwc->c", t_final, grad_image)
        grads = (total[:, 0:2], total[:, 2:5], total[:, 6:], total[:, 5], g_bg)
        return tuple(g.astype(dt) for g, dt in zip(grads, dtypes))
    finally:
        _SUMS.give(out)


def median_depth(means2d, conics, opacities, depths, radii, planes, width: int, height: int, t_final,
                 threads: int | None = None, band: float = 0.0) -> np.ndarray:
    """The median depth [H, W] (float64) of a render whose final transmittance is t_final [H, W]: per pixel,
    the mean depth on their planes (planes [N, 15], depth.depth_planes) of the Gaussians over which the running
    opacity crosses the band (1/2 -+ band) of the pixel's (band 0: the one at which it reaches half; kernel
    median_tiles); 0 where t_final = 1. Forward only (the exports read it)."""
    means2d, conics, opacities, planes, t_final = _f64(means2d, conics, opacities, planes, t_final)
    radii = np.ascontiguousarray(radii, np.int32)
    bins = bin_local(means2d, conics, opacities, depths, radii, width, height, threads)
    out = np.empty((height, width))
    local = bins.local(planes)
    _run(median_tiles, threads, lambda w: (*bins.rows, local, bins.offsets, bins.ids, width, height, t_final,
                                           float(band), out))
    return out
