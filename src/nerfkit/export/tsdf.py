"""TSDF fusion of rendered depth: a truncated signed distance on a grid, from many views.

After Curless & Levoy (1996), with the field's own renders as the range images. View k (a
pinhole camera: intrinsics (fx, fy, cx, cy), camera-to-world c2w_k, OpenGL axes) renders
z-depth D_k(u, v) and opacity A_k(u, v). A grid point x lands in pixel (u, v) at z-depth z;
its signed distance along the view's axis to the rendered surface is

    s_k(x) = D_k(u, v) - z                  (> 0: in front of the surface)

and, when x falls in the image in front of the camera, the view adds a value f_k with weight w_k:

    free pixel (A_k < 1/2: the ray goes through: background, outside the mask)   f_k = +1,                 w_k = 1 - A_k
    surface pixel (A_k >= 1/2) with s_k >= -tau                                f_k = clip(s_k / tau, -1, 1), w_k = A_k
    surface pixel with s_k < -tau                                              nothing (hidden behind it)

(a pixel is as sure of its surface as it is opaque), and the fused value is the weighted mean
F(x) = sum_k w_k f_k / W(x), W(x) = sum_k w_k. The surface is F = 0 (marching cubes). A point that some view has in
its image but that every such view sees hidden behind a surface (W = 0, seen > 0) is inside an
object; a point no view has in its image is unknown. The surface is bounded by the views' free
pixels: a point some photo shows background through cannot stay inside (its +1 pulls F up).
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import NerfkitError
from nerfkit.export.carve import pixel_footprint
from nerfkit.export.grid import grid_axis
from nerfkit.export.visibility import render_views

A_FREE = 0.5  # a pixel less opaque than this shows free space all along its ray
TRUNC_CELLS = 3.0  # tau: this many grid cells, or TRUNC_PIXELS pixel footprints at the centre, the larger
TRUNC_PIXELS = 2.0
SLAB_POINTS = 1 << 19  # grid points fused per compiled call


def project(x: jnp.ndarray, c2w: jnp.ndarray, intr: jnp.ndarray):
    """Pinhole projection of points x [M, 3]: (u, v, z) [M] with z the z-depth (OpenGL: the camera
    looks down -z; p = R^T (x - o), z = -p_z, u = fx p_x / z + cx, v = -fy p_y / z + cy)."""
    p = (x - c2w[:3, 3]) @ c2w[:3, :3]
    z = -p[:, 2]
    zs = jnp.where(z > 1e-6, z, 1.0)
    return intr[0] * p[:, 0] / zs + intr[2], -intr[1] * p[:, 1] / zs + intr[3], z


def view_terms(x, c2w, intr, depth, opacity, tau):
    """One view's (w f [M], w [M], in_image [M]) for points x [M, 3] (module docstring); depth and
    opacity [H, W] are read at the pixel each point falls in (nearest: no blending across edges)."""
    h, w = depth.shape
    u, v, z = project(x, c2w, intr)
    in_image = (z > 1e-6) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    iu = jnp.clip(jnp.floor(u).astype(jnp.int32), 0, w - 1)
    iv = jnp.clip(jnp.floor(v).astype(jnp.int32), 0, h - 1)
    d, a = depth[iv, iu], opacity[iv, iu]
    free = a < A_FREE
    s = d - z
    f = jnp.where(free, 1.0, jnp.clip(s / tau, -1.0, 1.0))
    wgt = jnp.where(in_image & (free | (s >= -tau)), jnp.where(free, 1.0 - a, a), 0.0)
    return wgt * f, wgt, in_image.astype(jnp.float32)


@jax.jit
def fuse_points(x, c2w, intr, depth, opacity, tau):
    """(sum_k w_k f_k [M], W [M], seen [M]) over the views c2w [V, 4, 4], intr [V, 4], depth and opacity
    [V, H, W] for points x [M, 3] (a scan over views: memory stays O(M))."""
    def body(acc, view):
        f, w, s = view_terms(x, *view, tau)
        return (acc[0] + f, acc[1] + w, acc[2] + s), None

    zero = jnp.zeros(x.shape[0], jnp.float32)
    (fsum, wsum, seen), _ = jax.lax.scan(body, (zero, zero, zero), (c2w, intr, depth, opacity))
    return fsum, wsum, seen


def truncation(h: float, pixel: float) -> float:
    """tau = max(TRUNC_CELLS h, TRUNC_PIXELS pixel): a few grid cells, and never finer than the
    renders' own depth resolution (pixel: one pixel's footprint at the scene centre)."""
    return max(TRUNC_CELLS * h, TRUNC_PIXELS * pixel)


def fuse_grid(axis: np.ndarray, c2w: np.ndarray, intr: np.ndarray, depth: np.ndarray, opacity: np.ndarray,
              tau: float, progress=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, W, seen), each float32 [N, N, N], on the grid axis^3 (C order: x, y, z), fused from the
    views (fuse_points), in slabs of whole x-slices of about SLAB_POINTS points (one compile)."""
    n = len(axis)
    per = max(1, SLAB_POINTS // (n * n))
    f = np.zeros((n, n, n), np.float32)
    w = np.zeros_like(f)
    seen = np.zeros_like(f)
    views = tuple(jnp.asarray(a, jnp.float32) for a in (c2w, intr, depth, opacity))
    gy, gz = np.meshgrid(axis, axis, indexing="ij")
    slabs = range(0, n, per)
    for i0 in (progress(slabs) if progress else slabs):
        xs = np.resize(axis[i0:i0 + per], per)  # the last slab repeats points: one compiled shape
        pts = np.stack(np.broadcast_arrays(xs[:, None, None], gy[None], gz[None]), -1).reshape(-1, 3)
        fs, ws, ss = (np.asarray(a).reshape(per, n, n) for a in fuse_points(jnp.asarray(pts), *views, tau))
        k = min(per, n - i0)
        f[i0:i0 + k], w[i0:i0 + k], seen[i0:i0 + k] = fs[:k], ws[:k], ss[:k]
    return f, w, seen


def tsdf_volume(fsum: np.ndarray, weight: np.ndarray, seen: np.ndarray, watertight: bool):
    """(F [N, N, N], known bool [N, N, N]): the mean F = fsum / W where W > 0. watertight: every point
    is known, W = 0 points some view has in its image are inside (-1), the others outside (+1);
    else the W = 0 points are unknown (marching cubes skips the cubes that touch them)."""
    f = np.where(weight > 0, fsum / np.maximum(weight, 1e-9), 0.0).astype(np.float32)
    if watertight:
        f = np.where(weight > 0, f, np.where(seen > 0, -1.0, 1.0)).astype(np.float32)
        return f, np.ones(f.shape, bool)
    return f, weight > 0


def cube_mask(known: np.ndarray) -> np.ndarray:
    """bool [N, N, N]: the cubes whose 8 corners are all known, each named by its highest corner (as
    scikit-image's marching_cubes reads its mask: mask[i, j, k] lets the cube [i-1, i] x [j-1, j] x [k-1, k]
    through)."""
    k = known
    m = k[:-1, :-1, :-1] & k[1:, :-1, :-1] & k[:-1, 1:, :-1] & k[:-1, :-1, 1:] \
        & k[1:, 1:, :-1] & k[1:, :-1, 1:] & k[:-1, 1:, 1:] & k[1:, 1:, 1:]
    return np.pad(m, ((1, 0), (1, 0), (1, 0)))


def zero_surface(f: np.ndarray, known: np.ndarray, bound: float, watertight: bool):
    """Marching cubes of F = 0 on the grid axis^3 of [-B, B]^3: (vertices float32 [V, 3], faces int64
    [F, 3]), wound so normals point to F > 0 (outwards). watertight: F is padded with a layer of +1,
    so a surface cut by the box is closed on it; else only cubes with all corners known are used."""
    from skimage.measure import marching_cubes

    n = f.shape[0]
    h = 2.0 * bound / (n - 1)
    if watertight:
        vol, mask, shift = np.pad(f, 1, constant_values=1.0), None, h
    else:
        vol, mask, shift = f, cube_mask(known), 0.0
    verts, faces, _, _ = marching_cubes(vol, level=0.0, spacing=(h, h, h), mask=mask, allow_degenerate=False)
    verts = np.clip(verts - (bound + shift), -bound, bound)
    return verts.astype(np.float32), faces.astype(np.int64)


FUSION_VIEWS = 64  # default: about this many training views are rendered and fused
PIXELS_PER_CELL = 1  # ... this many pixels across per grid cell (the depth maps resolve what the grid does)


def tsdf_surface(run, bound: float, resolution: int, every: int | None, data, watertight: bool, progress: bool,
                 log) -> tuple[np.ndarray, np.ndarray, dict]:
    """The fused surface in the normalised frame: (verts [V, 3], faces [F, 3], record fields). Renders
    every `every`-th training view (default: about FUSION_VIEWS; PIXELS_PER_CELL x resolution pixels
    wide), fuses their depth on the grid of [-bound, bound]^3 and takes F = 0."""
    t0 = time.perf_counter()
    views = render_views(run, every=every, data=data, pinhole=True, progress=progress, target=FUSION_VIEWS,
                         width=PIXELS_PER_CELL * resolution)
    t_render = time.perf_counter() - t0
    axis = grid_axis(bound, resolution)
    h = float(axis[1] - axis[0])
    tau = truncation(h, pixel_footprint(views.c2w, views.cameras))
    log(f"mesh: TSDF fusion of {len(views.c2w)} rendered training views (every {views.every}) on a {resolution}^3 "
        f"grid over the box [-{bound:g}, {bound:g}]^3 (h = {h:.4g}), truncation {tau:.4g}")
    bar = (lambda it: tqdm(it, desc="fuse", unit="slab", leave=False)) if progress else None
    fsum, weight, seen = fuse_grid(axis, views.c2w, views.intrinsics, views.depth, views.opacity, tau, bar)
    f, known = tsdf_volume(fsum, weight, seen, watertight)
    if not ((f[known] < 0).any() and (f[known] > 0).any()):
        raise NerfkitError("no surface: no rendered training view is opaque inside the box (is the run trained? "
                           "for an unbounded scene, try a larger --box)")
    verts, faces = zero_surface(f, known, bound, watertight)
    return verts, faces, {"views": len(views.c2w), "every": views.every, "view_size": list(views.depth.shape[2:0:-1]),
                          "truncation": tau,
                          "known_fraction": float(known.mean()), "render_seconds": round(t_render, 2)}
