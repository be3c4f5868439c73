"""The "pallas" rasteriser backend (backends.py): tile rasterisation, forward and backward, as JAX Pallas
kernels that compile to Triton on a GPU (inside jit: no host round trip) and run in Pallas's interpret
mode on a CPU (the same kernel source, for tests; far slower than the numba backend).

    image, alpha = rasterize_pallas(means2d, conics, colors, opacities, depths, radii, background, W, H)

renders the image defined in reference.py. Layout (every array on the device):

1. Preparation (plain JAX). Gaussians are sorted front to back (a stable argsort of the depths) and
   padded with invisible ones to a multiple of CHUNK; each gets the tile rectangle that holds its
   alpha-test ellipse d^T Q d <= s(o) (as tiles_geometry.tile_rects, plus one pixel of slack; empty when
   culled, not positive definite, or too faint to pass the alpha test anywhere). Parameters are laid out
   as rows (params [6, M]: m_x, m_y, a, b, c, o; colours [C, M]; rects [4, M]: tx0, tx1, ty0, ty1, ends
   exclusive) so that a kernel loads one Gaussian's values as scalars and a chunk's rectangles as vectors.
2. Forward kernel, one program per 16 x 16 tile, its 256 pixels a vector: chunks of CHUNK Gaussians
   are taken front to back; a chunk none of whose rectangles holds the tile is skipped on one vector
   test, otherwise each Gaussian whose rectangle holds the tile is blended into all 256 pixels by the
   reference's per-pixel rules (alpha test, 3-sigma cut, T_MIN stop). The program stops blending when
   every pixel is done or the list ends. Out: colour + T background, T_final, per tile, and where S > 1
   the tile's state (T, done, accumulated colour) at the start of each of S segments of the chunks
   (checkpoints; written for every segment, also after the tile is done).
3. Backward kernel, one program per (tile, segment): from that segment's checkpoint, front to back
   through its chunks with the same arithmetic (so the same pixels blend the same Gaussians). S is 1
   for images of many tiles; a small image's few tiles are split into segments so that the GPU has
   about PROGRAMS programs to run at once (at 200 x 200, 169 tiles alone left most of an H200 idle,
   each program's serial walk exposed). It uses the forward's colour: the colour behind Gaussian k is
   B_k = colour - A_k, A_k = sum_{j <= k} T_j alpha_j c_j, so no division back through (1 - alpha).
   For a loss with G = dL/dcolour [C] and g_T = dL/dT_final at a pixel:

       dL/dc_k     += T_k alpha_k G
       dL/dalpha_k += T_k c_k . G - (B_k . G + g_T T_final) / (1 - alpha_k)

   and from alpha_k on as in tiles_numba.py (unclamped alphas only: dL/do = e^{-sigma} dL/dalpha,
   dL/dsigma = -alpha dL/dalpha, dsigma/dm = (a d_x + b d_y, b d_x + c d_y), dsigma/d(a, b, c) =
   (d_x^2 / 2, d_x d_y, d_y^2 / 2)). Each Gaussian's sums over the tile's pixels are added to its
   row of the gradient array with atomic adds (tiles and segments run concurrently). dL/dbackground = sum T_final G.

Edge tiles are computed whole and cut; their outside pixels get zero cotangents. depths and radii get
no gradient (the order and the culling are piecewise constant).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
from jax.experimental import pallas as pl
from jax.experimental.pallas import triton as plt

from nerfkit.models.splat.backends import Backend
from nerfkit.models.splat.reference import ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN

TILE = 16
PIX = TILE * TILE  # a tile's pixels, one vector (a power of two, as Triton wants)
CHUNK = 32  # Gaussians per rectangle test (a power of two)
PROGRAMS = 2048  # the backward's (tile, segment) programs to aim for when the image has fewer tiles
MAX_SEGMENTS = 16
NUM_WARPS = 4  # Triton: 128 threads per tile program, two pixels each
_LOG_ALPHA_MIN = math.log(ALPHA_MIN)
# Names that moved between JAX versions (the lowest allowed, 0.4.35, has the older ones)
_CompilerParams = getattr(plt, "CompilerParams", None) or plt.TritonCompilerParams
_atomic_add = getattr(plt, "atomic_add", None) or pl.atomic_add


def interpret_default() -> bool:
    """Run the kernels in Pallas's interpret mode unless JAX's default device is a GPU."""
    return jax.default_backend() != "gpu"


def tile_rects(means2d, conics, opacities, radii, width: int, height: int) -> jax.Array:
    """Tile rectangles [4, N] int32 (tx0, tx1, ty0, ty1; ends exclusive) holding each Gaussian's alpha-test
    ellipse d^T Q d <= s(o), s(o) = 2 min(SIGMA_MAX, log(o / ALPHA_MIN)) (with rounding slack); the
    pixel box is m +- h, h_x = min(r + 1, sqrt(s Sigma'_xx)), plus one pixel. Empty (0, 0, 0, 0) for a
    Gaussian that shows nowhere: culled (r = 0), Q not positive definite, o < ALPHA_MIN or off-image."""
    dt = means2d.dtype
    a, b, c = conics[:, 0], conics[:, 1], conics[:, 2]
    o = opacities
    det = a * c - b * b
    span = 2.0 * jnp.minimum(SIGMA_MAX, jnp.log(jnp.maximum(o, ALPHA_MIN)) - _LOG_ALPHA_MIN) * (1.0 + 1e-4) + 1e-6
    mx, my = means2d[:, 0], means2d[:, 1]
    ok = ((radii > 0) & (a > 0) & (det > 0) & (o >= ALPHA_MIN) & jnp.isfinite(mx) & jnp.isfinite(my))
    safe_det = jnp.where(ok, det, 1.0)
    r1 = radii.astype(dt) + 1.0
    hx = jnp.minimum(r1, jnp.sqrt(jnp.maximum(span * c / safe_det, 0.0)))
    hy = jnp.minimum(r1, jnp.sqrt(jnp.maximum(span * a / safe_det, 0.0)))
    j0 = jnp.maximum(0.0, jnp.floor(mx - hx - 0.5))
    j1 = jnp.minimum(width - 1.0, jnp.floor(mx + hx - 0.5) + 1.0)
    i0 = jnp.maximum(0.0, jnp.floor(my - hy - 0.5))
    i1 = jnp.minimum(height - 1.0, jnp.floor(my + hy - 0.5) + 1.0)
    ok = ok & (j0 <= j1) & (i0 <= i1)
    big = float(max(width, height))  # keep the casts in range for far-away means
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    tx0 = jnp.clip(j0, 0, big).astype(jnp.int32) // TILE
    tx1 = jnp.minimum(tiles_x, jnp.clip(j1, 0, big).astype(jnp.int32) // TILE + 1)
    ty0 = jnp.clip(i0, 0, big).astype(jnp.int32) // TILE
    ty1 = jnp.minimum(tiles_y, jnp.clip(i1, 0, big).astype(jnp.int32) // TILE + 1)
    return jnp.where(ok[None], jnp.stack([tx0, tx1, ty0, ty1]), 0)


def prepare(means2d, conics, colors, opacities, depths, radii, width: int, height: int):
    """(order [N], params [6, M], colors [C, M], rects [4, M]): the Gaussians front to back (order: their
    indices), padded with empty rectangles to M = a multiple of CHUNK (at least one chunk)."""
    n = means2d.shape[0]
    m = max(CHUNK, -(-n // CHUNK) * CHUNK)
    order = jnp.argsort(jax.lax.stop_gradient(depths), stable=True)
    params = jnp.concatenate([means2d, conics, opacities[:, None]], 1)[order].T
    rects = tile_rects(means2d, conics, opacities, radii, width, height)[:, order]
    pad = ((0, 0), (0, m - n))
    return order, jnp.pad(params, pad), jnp.pad(colors[order].T, pad), jnp.pad(rects, pad)


def _tile_pixels(tiles_x: int, dtype):
    """(tile x, tile y, p_x [PIX], p_y [PIX]): this program's tile and its pixel centres, row-major."""
    t = pl.program_id(0)
    tx, ty = t % tiles_x, t // tiles_x
    lane = jax.lax.broadcasted_iota(jnp.int32, (PIX,), 0)
    px = (tx * TILE + lane % TILE).astype(dtype) + 0.5
    py = (ty * TILE + lane // TILE).astype(dtype) + 0.5
    return tx, ty, px, py


def _holds(rects_ref, idx, tx, ty):
    """Whether the rectangle(s) rects_ref[:, idx] hold tile (tx, ty) (idx a scalar or a pl.ds)."""
    return (rects_ref[0, idx] <= tx) & (tx < rects_ref[1, idx]) & (rects_ref[2, idx] <= ty) & (ty < rects_ref[3, idx])


def _alpha(params_ref, g, px, py):
    """Gaussian g at the pixel centres: (alpha [PIX] with the skip rules applied (0: skipped), e^{-sigma},
    unclamped (o e^{-sigma} < ALPHA_MAX), d_x, d_y, a, b, c)."""
    mx, my, a, b, c, o = (params_ref[j, g] for j in range(6))
    dx, dy = mx - px, my - py
    sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
    inside = (sigma >= 0.0) & (sigma <= SIGMA_MAX)
    e = jnp.exp(-jnp.where(inside, sigma, 0.0))
    raw = o * e
    alpha = jnp.minimum(ALPHA_MAX, raw)
    alpha = jnp.where(inside & (alpha >= ALPHA_MIN), alpha, 0.0)
    return alpha, e, raw < ALPHA_MAX, dx, dy, a, b, c


def _start_state(dtype, n_ch: int):
    """A tile's state before its first Gaussian: (T = 1 [PIX], done = 0 [PIX] int32, acc = n_ch x 0 [PIX])."""
    zeros = jnp.zeros((PIX,), dtype)
    return zeros + 1.0, jnp.zeros((PIX,), jnp.int32), tuple(zeros for _ in range(n_ch))


def _blend_step(alpha, colour, state):
    """(state after, blend [PIX] bool, w [PIX]): one Gaussian of alpha [PIX] and colour (C scalars) blended
    into the tile's state (T, done, acc) where it blends (not done, alpha > 0 and T (1 - alpha) >= T_MIN),
    w = alpha T there (0 elsewhere); a pixel where T would drop below T_MIN is done instead. Both kernels
    blend through this, so they make the same decisions."""
    trans, done, acc = state
    next_t = trans * (1.0 - alpha)
    live = (done == 0) & (alpha > 0.0)
    stop = live & (next_t < T_MIN)
    blend = live & ~stop
    w = jnp.where(blend, alpha * trans, 0.0)
    acc = tuple(a + w * c for a, c in zip(acc, colour))
    return (jnp.where(blend, next_t, trans), jnp.where(stop, 1, done), acc), blend, w


def segment_count(n_tiles: int, n_chunks: int) -> int:
    """S, the backward's segments per tile: ceil(PROGRAMS / n_tiles), at most MAX_SEGMENTS and n_chunks."""
    return max(1, min(n_chunks, MAX_SEGMENTS, -(-PROGRAMS // n_tiles)))


def _segment_chunks(s, n_chunks: int, segments: int):
    """(first chunk, end chunk) of segment s: floor(s n / S) .. floor((s + 1) n / S), never empty for S <= n."""
    return s * n_chunks // segments, (s + 1) * n_chunks // segments


def _scan_tile(rects_ref, tx, ty, c0, c1, step, state):
    """Run step(g, state) over the Gaussians of chunks c0 .. c1 - 1 whose rectangles hold the tile, front to
    back, a chunk at a time (a chunk with none is skipped on one vector test); stop early once state[1]
    (done [PIX]) is all 1."""
    def chunk(carry):
        ci, st = carry
        base = ci * CHUNK
        hit = _holds(rects_ref, pl.ds(base, CHUNK), tx, ty)

        def each(k, s):
            g = base + k
            return jax.lax.cond(_holds(rects_ref, g, tx, ty), partial(step, g), lambda s: s, s)

        st = jax.lax.cond(jnp.max(hit.astype(jnp.int32)) > 0, lambda s: jax.lax.fori_loop(0, CHUNK, each, s),
                          lambda s: s, st)
        return ci + 1, st

    def more(carry):
        ci, st = carry
        return (ci < c1) & (jnp.min(st[1]) == 0)

    return jax.lax.while_loop(more, chunk, (jnp.int32(c0), state))[1]


def _forward_kernel(params_ref, colors_ref, rects_ref, bg_ref, image_ref, tfinal_ref, ckpt_ref, *, tiles_x,
                    n_chunks, n_ch, segments):
    tx, ty, px, py = _tile_pixels(tiles_x, params_ref.dtype)
    t = pl.program_id(0)

    def step(g, st):
        colour = tuple(colors_ref[ch, g] for ch in range(n_ch))
        return _blend_step(_alpha(params_ref, g, px, py)[0], colour, st)[0]

    def segment(s, st):  # checkpoint [s]: the state before segment s (T, done, acc as rows of one array)
        if segments > 1:  # one segment starts from the empty state: nothing to keep
            for j, row in enumerate((st[0], st[1].astype(st[0].dtype), *st[2])):
                ckpt_ref[s, j, t, :] = row
        return _scan_tile(rects_ref, tx, ty, *_segment_chunks(s, n_chunks, segments), step, st)

    trans, _, acc = jax.lax.fori_loop(0, segments, segment, _start_state(params_ref.dtype, n_ch))
    for ch in range(n_ch):
        image_ref[ch, t, :] = acc[ch] + trans * bg_ref[ch]
    tfinal_ref[t, :] = trans


def _backward_kernel(params_ref, colors_ref, rects_ref, image_ref, tfinal_ref, gimg_ref, gt_ref, ckpt_ref, grads_in,
                     grads_ref, *, tiles_x, n_chunks, n_ch, segments):
    del grads_in  # aliased to grads_ref (zeros in), which the atomic adds accumulate into
    tx, ty, px, py = _tile_pixels(tiles_x, params_ref.dtype)
    t, s = pl.program_id(0), pl.program_id(1)
    colour = tuple(image_ref[ch, t, :] for ch in range(n_ch))
    gimg = tuple(gimg_ref[ch, t, :] for ch in range(n_ch))
    g_end = gt_ref[t, :] * tfinal_ref[t, :]  # g_T T_final

    def step(g, st):
        trans = st[0]  # T before this Gaussian
        col = tuple(colors_ref[ch, g] for ch in range(n_ch))
        alpha, e, unclamped, dx, dy, a, b, c = _alpha(params_ref, g, px, py)
        after, blend, w = _blend_step(alpha, col, st)
        acc = after[2]  # A_k
        d_alpha = 0.0
        behind = g_end
        for ch in range(n_ch):
            d_alpha = d_alpha + trans * col[ch] * gimg[ch]
            behind = behind + (colour[ch] - acc[ch]) * gimg[ch]
        d_alpha = d_alpha - behind / (1.0 - alpha)
        live = blend & unclamped
        d_sigma = jnp.where(live, -alpha * d_alpha, 0.0)
        sums = (d_sigma * (a * dx + b * dy), d_sigma * (b * dx + c * dy), 0.5 * d_sigma * dx * dx,
                d_sigma * dx * dy, 0.5 * d_sigma * dy * dy, jnp.where(live, e * d_alpha, 0.0))
        sums = sums + tuple(w * gimg[ch] for ch in range(n_ch))
        for j, total in enumerate(sums):
            _atomic_add(grads_ref, (jnp.int32(j), g), jnp.sum(total))
        return after

    start = _start_state(params_ref.dtype, n_ch)
    if segments > 1:
        start = (ckpt_ref[s, 0, t, :], ckpt_ref[s, 1, t, :].astype(jnp.int32),
                 tuple(ckpt_ref[s, 2 + ch, t, :] for ch in range(n_ch)))
    _scan_tile(rects_ref, tx, ty, *_segment_chunks(s, n_chunks, segments), step, start)


def _grid(width: int, height: int):
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    return tiles_x, tiles_y, tiles_x * tiles_y


def _untile(x, width: int, height: int):
    """[..., n_tiles, PIX] -> [..., H, W]: tiles (row-major) back to an image, edge tiles cut."""
    tiles_x, tiles_y, _ = _grid(width, height)
    lead = x.shape[:-2]
    x = x.reshape(*lead, tiles_y, tiles_x, TILE, TILE)
    x = jnp.moveaxis(x, -2, -3).reshape(*lead, tiles_y * TILE, tiles_x * TILE)
    return x[..., :height, :width]


def _tile(x, width: int, height: int):
    """[..., H, W] -> [..., n_tiles, PIX], zero-padded to whole tiles (the inverse of _untile)."""
    tiles_x, tiles_y, n_tiles = _grid(width, height)
    lead = x.shape[:-2]
    pad = [(0, 0)] * len(lead) + [(0, tiles_y * TILE - height), (0, tiles_x * TILE - width)]
    x = jnp.pad(x, pad).reshape(*lead, tiles_y, TILE, tiles_x, TILE)
    return jnp.moveaxis(x, -3, -2).reshape(*lead, n_tiles, PIX)


def _params():
    return _CompilerParams(num_warps=NUM_WARPS, num_stages=1)


def _kernel_args(prepared, width: int, height: int, segments: int | None):
    """(n_tiles, S, the kernels' static arguments) for the prepared Gaussians; segments None: segment_count."""
    params, colors = prepared[1], prepared[2]
    tiles_x, _, n_tiles = _grid(width, height)
    n_chunks = params.shape[1] // CHUNK
    segments = segment_count(n_tiles, n_chunks) if segments is None else max(1, min(int(segments), n_chunks))
    return n_tiles, segments, dict(tiles_x=tiles_x, n_chunks=n_chunks, n_ch=colors.shape[0], segments=segments)


def _forward(prepared, background, width, height, interpret, segments):
    _, params, colors, rects = prepared
    n_ch, dt = colors.shape[0], params.dtype
    n_tiles, segments, static = _kernel_args(prepared, width, height, segments)
    # the checkpoints [S, T, done, acc..., tile, pixel]; with one segment a placeholder nothing writes or reads
    ckpt = (segments, 2 + n_ch, n_tiles, PIX) if segments > 1 else (1, 1, 1, PIX)
    return pl.pallas_call(
        partial(_forward_kernel, **static), grid=(n_tiles,), interpret=interpret, compiler_params=_params(),
        name="splat_forward",
        out_shape=(jax.ShapeDtypeStruct((n_ch, n_tiles, PIX), dt), jax.ShapeDtypeStruct((n_tiles, PIX), dt),
                   jax.ShapeDtypeStruct(ckpt, dt)),
    )(params, colors, rects, background)


def _backward(prepared, image_t, tfinal_t, gimg_t, gt_t, ckpt, width, height, interpret, segments):
    _, params, colors, rects = prepared
    n_ch, dt = colors.shape[0], params.dtype
    n_tiles, segments, static = _kernel_args(prepared, width, height, segments)
    zeros = jnp.zeros((6 + n_ch, params.shape[1]), dt)
    return pl.pallas_call(
        partial(_backward_kernel, **static), grid=(n_tiles, segments), interpret=interpret,
        compiler_params=_params(), name="splat_backward", out_shape=jax.ShapeDtypeStruct(zeros.shape, dt),
        input_output_aliases={8: 0},
    )(params, colors, rects, image_t, tfinal_t, gimg_t, gt_t, ckpt, zeros)


@partial(jax.custom_vjp, nondiff_argnums=(7, 8, 9, 10))
def _rasterize(means2d, conics, colors, opacities, depths, radii, background, width, height, interpret, segments):
    return _rasterize_fwd(means2d, conics, colors, opacities, depths, radii, background, width, height,
                          interpret, segments)[0]


def _rasterize_fwd(means2d, conics, colors, opacities, depths, radii, background, width, height, interpret,
                   segments):
    prepared = prepare(means2d, conics, colors, opacities, depths, radii, width, height)
    image_t, tfinal_t, ckpt = _forward(prepared, background, width, height, interpret, segments)
    image = jnp.moveaxis(_untile(image_t, width, height), 0, -1)
    t_final = _untile(tfinal_t, width, height)
    return (image, t_final), (prepared, image_t, tfinal_t, ckpt, t_final)


def _rasterize_bwd(width, height, interpret, segments, res, cotangents):
    prepared, image_t, tfinal_t, ckpt, t_final = res
    g_img, g_t = cotangents
    n = prepared[0].shape[0]
    dt = image_t.dtype
    gimg_t = _tile(jnp.moveaxis(g_img.astype(dt), -1, 0), width, height)
    grads = _backward(prepared, image_t, tfinal_t, gimg_t, _tile(g_t.astype(dt), width, height), ckpt, width,
                      height, interpret, segments)
    order = prepared[0]
    grads = jnp.zeros((grads.shape[0], n), dt).at[:, order].set(grads[:, :n]).T  # back to the callers' order
    g_bg = jnp.einsum("hw,hwc->c", t_final, g_img.astype(dt))
    return grads[:, 0:2], grads[:, 2:5], grads[:, 6:], grads[:, 5], None, None, g_bg


_rasterize.defvjp(_rasterize_fwd, _rasterize_bwd)


def rasterize_pallas(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
                     interpret: bool | None = None, segments: int | None = None):
    """(image [H, W, C], alpha [H, W]) in the dtype of `colors`; interpret: None = interpret_default();
    segments: the backward's segments per tile (None: segment_count; at most the number of chunks)."""
    dt = colors.dtype
    interpret = interpret_default() if interpret is None else bool(interpret)
    image, t_final = _rasterize(jnp.asarray(means2d, dt), jnp.asarray(conics, dt), colors,
                                jnp.asarray(opacities, dt), jnp.asarray(depths, dt), jnp.asarray(radii, jnp.int32),
                                jnp.asarray(background, dt), int(width), int(height), interpret,
                                None if segments is None else int(segments))
    return image, 1.0 - t_final


BACKEND = Backend(
    name="pallas", summary="tile kernels in JAX Pallas: Triton on a GPU, interpret mode (slow, for tests) elsewhere",
    rasterize=rasterize_pallas)
