"""TSDF fusion of rendered depth: a truncated signed distance on a grid, from many views.

After Curless & Levoy (1996), with the field's own renders as the range images. View k (a
pinhole camera: intrinsics (fx, fy, cx, cy), camera-to-world c2w_k, OpenGL axes) renders
z-depth D_k(u, v) and opacity A_k(u, v). A grid point x lands in pixel (u, v) at z-depth z;
its signed distance along the view's axis to the rendered surface is

    s_k(x) = D_k(u, v) - z                  (> 0: in front of the surface)

and, when x falls in the image in front of the camera, the view adds a value f_k with weight w_k:

    free pixel (A_k < 1/2: the ray goes through: background, outside the mask)   f_k = +1,   w_k = 1 - A_k
    surface pixel (A_k >= 1/2) with s_k >= -tau          f_k = clip(s_k / tau, -1, 1),   w_k = A_k min(1, 1 + s_k / tau)
    surface pixel with s_k < -tau                                                 nothing (hidden behind it)

(a pixel is as sure of its surface as it is opaque, and less sure the farther behind it a point lies: Curless &
Levoy's weight ramp behind the surface. A view of a wall thinner than tau from behind would otherwise pull the
wall's front out towards the camera that sees the front: lego's 10-minute run, depth agreement on the held-out
views 0.950 without the ramp, 0.965 with it), and the fused value is the weighted mean
F(x) = sum_k w_k f_k / W(x), W(x) = sum_k w_k. The surface is F = 0 (marching cubes). A point that some view has in
its image but that every such view sees hidden behind a surface (W = 0, seen > 0) is inside an
object; a point no view has in its image is unknown. The surface is bounded by the views' free
pixels: a point some photo shows background through cannot stay inside (its +1 pulls F up).

D_k is the median depth (where the running opacity reaches half the ray's opacity, render/volume.py), not the expected
depth: a ray that grazes a soft edge and goes on to the floor has an expected depth between the
two, which is no surface at all.

The level. Where views disagree about an edge (each view's pixels put a depth jump a fraction
of a pixel to one side or the other), the rays that pass the edge vote +1 and F's zero lies
inside the field's surface: edges come out eroded (lego, 10-minute run: the held-out views show
the mesh's background through about a pixel of every foreground edge). So the surface is F = c,
with c chosen by the fused views themselves: for each candidate level the mesh is rasterised into
the views and scored by its depth agreement with them,

    score(c) = |{pixels where the mesh and the field (A >= 1/2) both are, within tol of D_k}|
               / |{pixels where the mesh or the field is}|        (summed over the views)

(an empty or a swollen mesh scores low), and the best c on LEVELS (refined by LEVEL_STEP / 2) is kept.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import NerfkitError
from nerfkit.export.carve import pixel_footprint
from nerfkit.export.fusion_kernel import camera_table, fuse_lines
from nerfkit.export.grid import grid_axis
from nerfkit.export.raster import rasterize
from nerfkit.export.visibility import Views, render_views

A_FREE = 0.5  # a pixel less opaque than this shows free space all along its ray
TRUNC_CELLS = 3.0  # tau: this many grid cells, or TRUNC_PIXELS pixel footprints at the centre, the larger
TRUNC_PIXELS = 2.0
SLAB_POINTS = 1 << 19  # grid points fused per compiled call


def project(x: jnp.ndarray, c2w: jnp.ndarray, intr: jnp.ndarray):
    """Pinhole projection of points x [M, 3]: (u, v, z) [M] with z the z-depth (OpenGL: the camera
    looks down -z; p = R^T (x - o), z = -p_z, u = fx p_x / z + cx, v = -fy p_y / z + cy; points with
    z <= 1e-6 are divided by 1). Arithmetic only, so numpy arrays stay numpy (no compile per shape)."""
    p = (x - c2w[:3, 3]) @ c2w[:3, :3]
    z = -p[:, 2]
    behind = z <= 1e-6
    zs = z + behind * (1.0 - z)
    return intr[0] * p[:, 0] / zs + intr[2], -intr[1] * p[:, 1] / zs + intr[3], z


def pixel_of(x, c2w, intr, h: int, w: int):
    """(u, v, z, in_image, iv, iu) [M] of points x [M, 3] in an H x W pinhole view (project): in_image where the
    point lies in front of the camera and inside the image, (iv, iu) the pixel it falls in (clamped to the image)."""
    u, v, z = project(x, c2w, intr)
    in_image = (z > 1e-6) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    iu = jnp.clip(jnp.floor(u).astype(jnp.int32), 0, w - 1)
    iv = jnp.clip(jnp.floor(v).astype(jnp.int32), 0, h - 1)
    return u, v, z, in_image, iv, iu


def view_terms(x, c2w, intr, depth, opacity, tau):
    """One view's (w f [M], w [M], in_image [M]) for points x [M, 3] (module docstring); depth and
    opacity [H, W] are read at the pixel each point falls in (nearest: no blending across edges)."""
    _, _, z, in_image, iv, iu = pixel_of(x, c2w, intr, *depth.shape)
    d, a = depth[iv, iu], opacity[iv, iu]
    free = a < A_FREE
    s = d - z
    f = jnp.where(free, 1.0, jnp.clip(s / tau, -1.0, 1.0))
    behind = jnp.clip(1.0 + s / tau, 0.0, 1.0)  # the ramp: 1 in front of the surface, 0 at tau behind it
    wgt = jnp.where(in_image & (free | (s >= -tau)), jnp.where(free, 1.0 - a, a * behind), 0.0)
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
              tau: float, progress=None, kernel: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, W, seen), each float32 [N, N, N], on the grid axis^3 (C order: x, y, z), fused from the
    views, in slabs of whole x-slices of about SLAB_POINTS points. kernel: "numba" (fusion_kernel.py, on the
    host's cores), "xla" (fuse_points, one compile) or "auto": numba where JAX computes on the CPU."""
    n = len(axis)
    per = max(1, SLAB_POINTS // (n * n))
    f = np.zeros((n, n, n), np.float32)
    w = np.zeros_like(f)
    seen = np.zeros_like(f)
    on_host = kernel == "numba" or (kernel == "auto" and jax.default_backend() == "cpu")
    if on_host:
        cams = camera_table(c2w, intr)
        depth, opacity = (np.ascontiguousarray(a, np.float32) for a in (depth, opacity))
    else:
        views = tuple(jnp.asarray(a, jnp.float32) for a in (c2w, intr, depth, opacity))
        gy, gz = np.meshgrid(axis, axis, indexing="ij")
    slabs = range(0, n, per)
    for i0 in (progress(slabs) if progress else slabs):
        k = min(per, n - i0)
        if on_host:
            fuse_lines(axis, i0, k, cams, depth, opacity, tau, A_FREE, (f[i0:i0 + k], w[i0:i0 + k], seen[i0:i0 + k]))
            continue
        xs = np.resize(axis[i0:i0 + per], per)  # the last slab repeats points: one compiled shape
        pts = np.stack(np.broadcast_arrays(xs[:, None, None], gy[None], gz[None]), -1).reshape(-1, 3)
        fs, ws, ss = (np.asarray(a).reshape(per, n, n) for a in fuse_points(jnp.asarray(pts), *views, tau))
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


SMOOTH_PIXELS = 0.5  # F is blurred by a Gaussian of this many pixel footprints (at the scene centre)


def smooth_volume(f: np.ndarray, known: np.ndarray, sigma: float) -> np.ndarray:
    """F [N, N, N] blurred by a Gaussian of std `sigma` grid cells over its known points (normalised
    convolution: (G * [known] F) / (G * [known]); unknown points keep their value).

    Each view's depth is sampled once per pixel, so the fused F carries ripples of a pixel's footprint
    whatever the grid: on exact depth maps of a sphere (24 views, tests/export/test_tsdf.py) the faces'
    normals are within 10 degrees of the true ones on 54% / 28% / 16% of the surface at 64 / 128 / 256
    grid points, and on 100% at all three after a blur of SMOOTH_PIXELS footprints, with the radius error
    halved (0.09 -> 0.04 px). A blur of a signed distance keeps a plane's zero in place."""
    from scipy.ndimage import gaussian_filter

    if sigma <= 0:
        return f
    k = known.astype(np.float32)
    blurred = gaussian_filter(np.where(known, f, 0.0).astype(np.float32), sigma) / np.maximum(gaussian_filter(k, sigma),
                                                                                              1e-6)
    return np.where(known, blurred, f).astype(np.float32)


def cube_mask(known: np.ndarray) -> np.ndarray:
    """bool [N, N, N]: the cubes whose 8 corners are all known, each named by its highest corner (as
    scikit-image's marching_cubes reads its mask: mask[i, j, k] lets the cube [i-1, i] x [j-1, j] x [k-1, k]
    through)."""
    k = known
    m = k[:-1, :-1, :-1] & k[1:, :-1, :-1] & k[:-1, 1:, :-1] & k[:-1, :-1, 1:] \
        & k[1:, 1:, :-1] & k[1:, :-1, 1:] & k[:-1, 1:, 1:] & k[1:, 1:, 1:]
    return np.pad(m, ((1, 0), (1, 0), (1, 0)))


def zero_surface(f: np.ndarray, known: np.ndarray, bound: float, watertight: bool, level: float = 0.0):
    """Marching cubes of F = level on the grid axis^3 of [-B, B]^3: (vertices float32 [V, 3], faces int64
    [F, 3]), wound so normals point to F > level (outwards). watertight: F is padded with a layer of +1,
    so a surface cut by the box is closed on it; else only cubes with all corners known are used."""
    from skimage.measure import marching_cubes

    n = f.shape[0]
    h = 2.0 * bound / (n - 1)
    if watertight:
        vol, mask, shift = np.pad(f, 1, constant_values=1.0), None, h
    else:
        vol, mask, shift = f, cube_mask(known), 0.0
    verts, faces, _, _ = marching_cubes(vol, level=level, spacing=(h, h, h), mask=mask, allow_degenerate=False)
    verts = np.clip(verts - (bound + shift), -bound, bound)
    return verts.astype(np.float32), faces.astype(np.int64)


LEVELS = (-0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5)  # candidate levels c of the surface F = c
LEVEL_STEP = 0.1
DEPTH_TOL = 0.01  # depth agreement: within this share of the box side 2B (as benchmarks/mesh_quality.py)


def depth_iou(verts: np.ndarray, faces: np.ndarray, c2w: np.ndarray, intr: np.ndarray, depth: np.ndarray,
              opacity: np.ndarray, tol: float) -> float:
    """score(c) of the module docstring for one mesh (normalised frame) in pinhole views c2w [V, 4, 4],
    intr [V, 4], depth and opacity [V, H, W]: pixels where mesh and field agree within tol, over the
    pixels where either is."""
    agree = either = 0
    for k in range(len(c2w)):
        u, v, z = project(np.asarray(verts, np.float32), np.asarray(c2w[k], np.float32), np.asarray(intr[k], np.float32))
        mesh = rasterize(np.stack([u, v], -1), np.where(z > 1e-6, z, -1.0), faces, *depth.shape[1:])[2]
        field = opacity[k] >= A_FREE
        covered = np.isfinite(mesh)
        agree += int(np.sum(covered & field & (np.abs(mesh - depth[k]) <= tol)))
        either += int(np.sum(covered | field))
    return agree / max(either, 1)


def best_level(f: np.ndarray, known: np.ndarray, bound: float, c2w, intr, depth, opacity) -> tuple[float, dict]:
    """(c, {c: score}): the level of LEVELS, then refined by +-LEVEL_STEP / 2 around the best, whose
    surface (cubes with every corner known) agrees best with the views (depth_iou, tol = DEPTH_TOL 2B)."""
    tol = DEPTH_TOL * 2.0 * bound
    scores: dict[float, float] = {}

    def score(c: float) -> float:
        c = round(c, 3)
        if c not in scores:
            try:
                verts, faces = zero_surface(f, known, bound, False, c)
            except (ValueError, RuntimeError):  # marching cubes: c outside the fused values, or no cube crosses it
                verts, faces = np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64)
            scores[c] = depth_iou(verts, faces, c2w, intr, depth, opacity, tol) if len(faces) else 0.0
        return scores[c]

    def rank(c: float) -> tuple[float, float]:
        return score(c), -abs(c)  # ties (e.g. no surface at all) go to the level nearest F = 0

    best = max(LEVELS, key=rank)
    best = max((best - LEVEL_STEP / 2, best, best + LEVEL_STEP / 2), key=rank)
    return round(best, 3), scores


FUSION_VIEWS = 64  # default: about this many training views are rendered and fused
# ... and this many for a model that renders whole images (splats): each view costs a fraction of a ray march,
# and its depth scatters from view to view (each view sorts and blends its own Gaussians), which more views
# average out (lego at 200 px, 150 views instead of 50: depth agreement +0.3 points, IoU the same; CHANGELOG)
FUSION_VIEWS_IMAGES = 160
CALIBRATION_EVERY = 2  # the level is chosen on every other fused view
PIXELS_PER_CELL = 1  # ... this many pixels across per grid cell (the depth maps resolve what the grid does)


def fused_surface(bound: float, axis: np.ndarray, c2w: np.ndarray, intr: np.ndarray, depth: np.ndarray,
                  opacity: np.ndarray, tau: float, smooth_cells: float, watertight: bool, progress=None):
    """(verts [V, 3], faces [F, 3], level c, {c: score}, known bool [N, N, N]): the views' z-depth and opacity
    [V, H, W] (pinhole c2w [V, 4, 4], intr [V, 4]) fused on the grid axis^3 of [-bound, bound]^3 (grid_axis;
    fuse_grid, tsdf_volume), blurred by smooth_cells grid cells (smooth_volume), cut at the level best_level
    picks on every CALIBRATION_EVERY-th view (zero_surface)."""
    f, known = tsdf_volume(*fuse_grid(axis, c2w, intr, depth, opacity, tau, progress), watertight)
    f = smooth_volume(f, known, smooth_cells)
    if not ((f[known] < 0).any() and (f[known] > 0).any()):
        raise NerfkitError("no surface: no rendered training view is opaque inside the box (is the run trained? "
                           "for an unbounded scene, try a larger --box)")
    calib = slice(None, None, CALIBRATION_EVERY)
    level, scores = best_level(f, known, bound, c2w[calib], intr[calib], depth[calib], opacity[calib])
    return (*zero_surface(f, known, bound, watertight, level), level, scores, known)


def tsdf_surface(run, bound: float, resolution: int, every: int | None, data, watertight: bool, progress: bool,
                 log, smooth: float = SMOOTH_PIXELS) -> tuple[np.ndarray, np.ndarray, dict, Views]:
    """The fused surface in the normalised frame: (verts [V, 3], faces [F, 3], record fields, the rendered
    views). Renders every `every`-th training view (default: about FUSION_VIEWS, FUSION_VIEWS_IMAGES for a model
    that renders whole images; PIXELS_PER_CELL x resolution pixels wide), fuses their median depth on the grid of
    [-bound, bound]^3 and takes the surface F = c at the level c best_level picks."""
    t0 = time.perf_counter()
    target = FUSION_VIEWS_IMAGES if run.model.supports.renders_images else FUSION_VIEWS
    views = render_views(run, every=every, data=data, pinhole=True, progress=progress, target=target,
                         width=PIXELS_PER_CELL * resolution, median=True)
    t_render = time.perf_counter() - t0
    axis = grid_axis(bound, resolution)
    h = float(axis[1] - axis[0])
    pixel = pixel_footprint(views.c2w, views.cameras)
    tau = truncation(h, pixel)
    log(f"mesh: TSDF fusion of {len(views.c2w)} rendered training views (every {views.every}) on a {resolution}^3 "
        f"grid over the box [-{bound:g}, {bound:g}]^3 (h = {h:.4g}), truncation {tau:.4g}")
    bar = (lambda it: tqdm(it, desc="fuse", unit="slab", leave=False)) if progress else None
    verts, faces, level, scores, known = fused_surface(bound, axis, views.c2w, views.intrinsics,
                                                       views.median, views.opacity, tau, smooth * pixel / h,
                                                       watertight, bar)
    log(f"mesh: surface at F = {level:g}, the level whose surface agrees best with the depth of "
        f"{len(views.c2w[::CALIBRATION_EVERY])} fused views (score {scores[level]:.4f}; at F = 0: {scores[0.0]:.4f})")
    return verts, faces, {"views": len(views.c2w), "every": views.every, "view_size": list(views.depth.shape[2:0:-1]),
                          "truncation": tau,
                          "smooth_pixels": smooth, "smoothing_cells": round(smooth * pixel / h, 3),
                          "level": level,
                          "level_scores": {f"{c:g}": round(v, 5) for c, v in sorted(scores.items())},
                          "known_fraction": float(known.mean()), "render_seconds": round(t_render, 2)}, views
