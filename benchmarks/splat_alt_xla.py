"""Benchmark candidate: the tile rasteriser in pure XLA, tiles padded to a fixed list length.

Not used by `rasterize` (benchmarks/splat_raster.py compares it with the numba kernels). All
shapes are static, so it jits and differentiates by autodiff anywhere (CPU or GPU):

1. Each live Gaussian gets the tile rectangle of its radius square (+1 px, as tiles_numba).
2. Its tile overlaps are expanded to a flat list of at most `max_overlaps` (tile, Gaussian)
   entries in depth order, then stably sorted by tile: each tile's run is depth-sorted.
3. Each tile gathers the first `max_per_tile` entries of its run (padding: opacity 0) and
   blends them for its 16 x 16 pixels with reference.blend (dense: no early exit, but the
   same T_MIN prefix rule), in chunks of tiles under jax.checkpoint to bound memory.

Exact (the same image as reference.py) when max_per_tile >= the longest tile list and
max_overlaps >= the number of overlaps; entries past either budget are silently dropped.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.models.splat.reference import blend, gaussian_alpha
from nerfkit.models.splat.tiles_numba import TILE


def tile_rects(means2d, radii, width: int, height: int):
    """(tx0, tx1, ty0, ty1) [N] int32 of the radius squares (+1 px slack); empty when radius is 0."""
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    h = jnp.where(radii > 0, radii + 1.0, -1.0)
    m = jax.lax.stop_gradient(means2d)
    j0 = jnp.clip(jnp.floor(m[:, 0] - h - 0.5), 0, width - 1)
    j1 = jnp.clip(jnp.floor(m[:, 0] + h - 0.5) + 1, 0, width - 1)
    i0 = jnp.clip(jnp.floor(m[:, 1] - h - 0.5), 0, height - 1)
    i1 = jnp.clip(jnp.floor(m[:, 1] + h - 0.5) + 1, 0, height - 1)
    empty = (radii <= 0) | (m[:, 0] - h - 0.5 > width) | (m[:, 0] + h - 0.5 < 0) | (m[:, 1] - h - 0.5 > height) | (
        m[:, 1] + h - 0.5 < 0)
    tx0, ty0 = (j0 // TILE).astype(jnp.int32), (i0 // TILE).astype(jnp.int32)
    tx1 = jnp.where(empty, tx0, jnp.minimum(tiles_x, j1 // TILE + 1).astype(jnp.int32))
    ty1 = jnp.where(empty, ty0, jnp.minimum(tiles_y, i1 // TILE + 1).astype(jnp.int32))
    return tx0, tx1, ty0, ty1


def tile_lists(means2d, depths, radii, width: int, height: int, max_per_tile: int, max_overlaps: int):
    """ids [n_tiles, max_per_tile] int32 (depth-sorted Gaussians of each tile, -1 = padding)."""
    n = means2d.shape[0]
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    n_tiles = tiles_x * tiles_y
    order = jnp.argsort(jax.lax.stop_gradient(depths), stable=True)
    tx0, tx1, ty0, ty1 = (r[order] for r in tile_rects(means2d, radii, width, height))
    count = (tx1 - tx0) * (ty1 - ty0)
    ends = jnp.cumsum(count)
    e = jnp.arange(max_overlaps)
    k = jnp.minimum(jnp.searchsorted(ends, e, side="right"), n - 1)  # rank of the entry's Gaussian
    local = e - (ends[k] - count[k])
    w = jnp.maximum(tx1[k] - tx0[k], 1)
    tile = (ty0[k] + local // w) * tiles_x + tx0[k] + local % w
    tile = jnp.where(e < ends[-1], tile, n_tiles)  # unused entries sort last
    tile_sorted, gauss = jax.lax.sort((tile, order[k].astype(jnp.int32)), num_keys=1, is_stable=True)
    starts = jnp.searchsorted(tile_sorted, jnp.arange(n_tiles))
    stops = jnp.searchsorted(tile_sorted, jnp.arange(n_tiles), side="right")
    pos = starts[:, None] + jnp.arange(max_per_tile)[None, :]
    return jnp.where(pos < stops[:, None], gauss[jnp.minimum(pos, max_overlaps - 1)], -1)


def rasterize_xla(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
                  max_per_tile: int, max_overlaps: int, tile_chunk: int = 16):
    """Image [H, W, C] and alpha [H, W] as reference.rasterize_reference (see the module docstring)."""
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    n_tiles = tiles_x * tiles_y
    ids = tile_lists(means2d, depths, radii, width, height, max_per_tile, max_overlaps)
    n_chunks = -(-n_tiles // tile_chunk)
    ids = jnp.concatenate([ids, jnp.full((n_chunks * tile_chunk - n_tiles, max_per_tile), -1, ids.dtype)])
    t = jnp.arange(n_chunks * tile_chunk)
    yy, xx = jnp.meshgrid(jnp.arange(TILE), jnp.arange(TILE), indexing="ij")
    pix = jnp.stack([(t[:, None] % tiles_x) * TILE + xx.ravel()[None] + 0.5,
                     (t[:, None] // tiles_x) * TILE + yy.ravel()[None] + 0.5], axis=-1).astype(means2d.dtype)

    @jax.checkpoint
    def one_tile(p, g):
        live = g >= 0
        gi = jnp.maximum(g, 0)
        alpha = gaussian_alpha(p, means2d[gi], conics[gi], jnp.where(live, opacities[gi], 0.0))
        return blend(alpha, colors[gi], background)

    def chunk(args):
        return jax.vmap(one_tile)(*args)

    color, t_final = jax.lax.map(chunk, (pix.reshape(n_chunks, tile_chunk, TILE * TILE, 2),
                                         ids.reshape(n_chunks, tile_chunk, max_per_tile)))
    n_ch = colors.shape[1]
    color = color.reshape(-1, TILE, TILE, n_ch)[:n_tiles].reshape(tiles_y, tiles_x, TILE, TILE, n_ch)
    color = color.transpose(0, 2, 1, 3, 4).reshape(tiles_y * TILE, tiles_x * TILE, n_ch)[:height, :width]
    t_final = t_final.reshape(-1, TILE, TILE)[:n_tiles].reshape(tiles_y, tiles_x, TILE, TILE)
    t_final = t_final.transpose(0, 2, 1, 3).reshape(tiles_y * TILE, tiles_x * TILE)[:height, :width]
    return color, 1.0 - t_final
