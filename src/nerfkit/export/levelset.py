"""The level-set surface (`nerfkit export mesh --method levelset`): density on a grid, marching cubes.

The density sigma is sampled at the N^3 points x_ijk = -B + (i, j, k) h of the scene box
[-B, B]^3 (h = 2B / (N - 1)), only where the occupancy grid says a cell is occupied (the other
points are empty by construction: their density was below the grid's threshold, far below any
surface level), slab by slab and in fixed-size chunks so memory stays bounded. The surface
is the level set sigma = T (scikit-image's marching cubes). The default level is

    T = ln 2 / h,

the density at which a ray crossing one grid cell gathers opacity 1 - exp(-T h) = 1/2: the
surface sits where one cell of the export grid would look half opaque. Faces no training view
sees are dropped (visibility.py), each vertex is then moved along its normal, within one cell,
to where a ray coming in from outside turns half opaque (half_opacity_snapper: the surface the
renders show). Where the capture has masks or an alpha channel, vertices that still fall on the
background of training photos move into the training silhouettes (carve.py: the level set
rounds and fattens contours by about a pixel), and faces the photos show background through are
dropped. Each vertex then takes the colour the field gives there seen along the inverse normal.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from scipy import ndimage
from tqdm.auto import tqdm

from nerfkit.core.errors import NerfkitError
from nerfkit.export.carve import (
    carve,
    pixel_footprint,
    training_silhouettes,
    used_vertices,
)
from nerfkit.export.grid import chunked, field_functions, grid_axis, slab_points
from nerfkit.export.surface import vertex_normals
from nerfkit.export.visibility import make_visibility, render_views
from nerfkit.run.folder import TrainedRun

SNAP_CELLS = 1.0  # how far (in grid cells) a vertex may move onto the half-opaque surface
CARVE_CELLS, CARVE_PIXELS = 2.0, 2.0  # how far a vertex may move into the training silhouettes: cells or pixels


def default_threshold(bound: float, resolution: int) -> float:
    """T = ln 2 / h with h = 2B / (N - 1): the density where one grid cell is half opaque."""
    return math.log(2.0) * (resolution - 1) / (2.0 * bound)


def occupied_mask(occupied_fn, axis: np.ndarray, cell: float, slab: int = 8) -> np.ndarray:
    """bool [N, N, N]: grid points in (or within one cell of) an occupied occupancy cell.

    occupied_fn: points [M, 3] -> bool [M]; cell: the occupancy cell's size in world units (the
    mask is dilated by that much, in case the grid's running maximum missed a thin part)."""
    n = len(axis)
    mask = np.zeros((n, n, n), bool)
    for i0 in range(0, n, slab):
        i1 = min(n, i0 + slab)
        mask[i0:i1] = chunked(occupied_fn, slab_points(axis, i0, i1)).reshape(i1 - i0, n, n)
    h = float(axis[1] - axis[0])
    k = max(1, math.ceil(cell / h))
    return ndimage.maximum_filter(mask, size=2 * k + 1)


def density_volume(density_fn, axis: np.ndarray, mask: np.ndarray | None, slab: int = 8,
                   progress: bool = False) -> np.ndarray:
    """float32 [N, N, N]: sigma at the grid points where `mask` (all when None), 0 elsewhere."""
    n = len(axis)
    vol = np.zeros((n, n, n), np.float32)
    for i0 in tqdm(range(0, n, slab), desc="density", unit="slab", disable=not progress, leave=False):
        i1 = min(n, i0 + slab)
        pts = slab_points(axis, i0, i1)
        sub = np.ones(len(pts), bool) if mask is None else mask[i0:i1].reshape(-1)
        if sub.any():
            part = vol[i0:i1].reshape(-1)
            part[sub] = chunked(density_fn, pts[sub])
            vol[i0:i1] = part.reshape(i1 - i0, n, n)
    return vol


def extract_surface(volume: np.ndarray, threshold: float, bound: float):
    """Marching cubes of the level set volume = threshold on the grid of `grid_axis(bound, N)`.

    The volume is padded with one layer of zeros, so a surface cut by the box is closed there
    (a watertight mesh). Faces wind so their normals point out of the dense region.
    Returns vertices float32 [V, 3] (normalised frame), faces int64 [F, 3]."""
    from skimage.measure import marching_cubes

    n = volume.shape[0]
    h = 2.0 * bound / (n - 1)
    padded = np.pad(volume, 1)
    verts, faces, _, _ = marching_cubes(padded, level=threshold, spacing=(h, h, h), gradient_direction="ascent",
                                        allow_degenerate=False)
    verts = np.clip(verts - (bound + h), -bound, bound)  # the closing layer lies on the box
    return verts.astype(np.float32), faces.astype(np.int64)


def half_opacity_snapper(density_fn, delta: float, k: int = 16):
    """A jitted function (x [M, 3], n [M, 3]) -> x' [M, 3] that moves each vertex x along its unit
    outward normal n onto the point where a ray coming in from outside becomes half opaque:

        t_j = delta - 2 delta j / (k - 1),  j = 0..k-1       (from x + delta n inwards to x - delta n)
        tau_j = sum_{i < j} (sigma_i + sigma_{i+1}) dt / 2,  sigma_i = sigma(x + t_i n),  dt = 2 delta / (k - 1)
        x' = x + t* n,  t* where 1 - exp(-tau) crosses 1/2 (linear between samples)

    The level set sigma = T is where the field is dense, not where it looks opaque; this moves
    the surface to where a pixel looking straight at it is half covered (the silhouette, for
    alpha > 0.5). Vertices whose short ray never reaches opacity 1/2 stay where they are."""
    t = jnp.asarray(np.linspace(delta, -delta, k), jnp.float32)
    dt = 2.0 * delta / (k - 1)

    @jax.jit
    def snap(x, n):
        sigma = density_fn((x[:, None, :] + t[None, :, None] * n[:, None, :]).reshape(-1, 3)).reshape(-1, k)
        trapezoids = 0.5 * (sigma[:, 1:] + sigma[:, :-1]) * dt
        tau = jnp.concatenate([jnp.zeros_like(sigma[:, :1]), jnp.cumsum(trapezoids, axis=1)], axis=1)
        opacity = 1.0 - jnp.exp(-tau)
        hit = opacity >= 0.5
        j = jnp.argmax(hit, axis=1)
        prev_j = jnp.maximum(j - 1, 0)
        prev = jnp.where(j > 0, jnp.take_along_axis(opacity, prev_j[:, None], 1)[:, 0], 0.0)
        cur = jnp.take_along_axis(opacity, j[:, None], 1)[:, 0]
        frac = jnp.clip((0.5 - prev) / jnp.maximum(cur - prev, 1e-6), 0.0, 1.0)
        t_star = jnp.where(j > 0, t[prev_j] + frac * (t[j] - t[prev_j]), t[0])
        return jnp.where(jnp.any(hit, axis=1)[:, None], x + t_star[:, None] * n, x)

    return snap


def seen_faces(verts: np.ndarray, faces: np.ndarray, seen_fn):
    """The faces some view sees (visibility.make_visibility: the centroid is the first surface
    there and the face turns towards the camera), and only the vertices they use:
    (verts [V', 3], faces [F', 3])."""
    tri = verts[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    keep = chunked(seen_fn, tri.mean(axis=1).astype(np.float32), normals.astype(np.float32))
    return used_vertices(verts, faces[keep])


def carve_mesh(run: TrainedRun, verts: np.ndarray, faces: np.ndarray, h: float, data, log):
    """(verts, faces, stats) carved into the training silhouettes (carve.py: moves of up to CARVE_CELLS
    grid cells of size h or CARVE_PIXELS pixels, whichever is longer), or None when the capture has no
    masks or alpha channel."""
    sil = training_silhouettes(run, data)
    if sil is None:
        log("mesh: the capture has neither masks nor an alpha channel; not carved to silhouettes")
        return None
    poses, cams, silhouettes = sil
    px = pixel_footprint(poses, cams)
    reach = max(CARVE_CELLS * h, CARVE_PIXELS * px)
    delta = min(h, px) / 8
    verts, faces, stats = carve(verts, vertex_normals(verts, faces), faces, poses, cams, silhouettes, delta,
                                math.ceil(reach / delta))
    stats["views"] = len(poses)
    moved = stats["moved_along_normal"] + stats["moved_otherwise"]
    log(f"mesh: {stats['outside']} vertices fell outside the silhouettes of {len(poses)} training views "
        f"(margin {stats['margin_px']:g} px, {stats['tolerance_views']} may disagree); {moved} moved in "
        f"(at most {reach:.3g}), {stats['absent']} could not and the {stats['dropped_faces']} faces using them were "
        f"dropped (--no-carve keeps them)")
    if not len(faces):
        raise NerfkitError("no face of the mesh lies inside the training silhouettes; check the masks, or pass "
                           "--no-carve")
    return verts, faces, stats


def levelset_surface(run: TrainedRun, bound: float, resolution: int, threshold: float | None, visible_only: bool, snap: bool,
                     every: int | None, data, carve: bool, progress: bool, log) -> tuple[np.ndarray, np.ndarray, dict]:
    """The level set's mesh in the normalised frame: (verts [V, 3], faces [F, 3], record fields).

    visible_only: keep only faces that some training view (every `every`-th) sees; snap: move the
    vertices onto the half-opaque surface (half_opacity_snapper); carve: keep the vertices inside the
    training silhouettes where the capture has masks or alpha (carve.py)."""
    h = 2.0 * bound / (resolution - 1)
    level = default_threshold(bound, resolution) if threshold is None else float(threshold)
    rule = "ln 2 / h (one grid cell half opaque)" if threshold is None else "--threshold"
    log(f"mesh: level set of the density on a {resolution}^3 grid over the box [-{bound:g}, {bound:g}]^3 "
        f"(h = {h:.4g}), threshold {level:.4g} ({rule})")
    density_fn, _, occupied_fn, cell = field_functions(run)
    axis = grid_axis(bound, resolution)
    mask = None if occupied_fn is None else occupied_mask(occupied_fn, axis, cell)
    vol = density_volume(density_fn, axis, mask, progress=progress)
    peak = float(vol.max())
    if not peak >= level:
        raise NerfkitError(f"nothing above the threshold {level:.4g} (the density peaks at {peak:.4g} in the box); "
                           f"try a lower --threshold")
    verts, faces = extract_surface(vol, level, bound)
    n_level_set = len(faces)
    if visible_only:
        views = render_views(run, every=every, data=data, pinhole=True, progress=progress)
        verts, faces = seen_faces(verts, faces, make_visibility(views, h))
        log(f"mesh: {len(faces)} of the level set's {n_level_set} faces are seen by {len(views.c2w)} training views "
            f"(the others lie inside objects or under them: --no-visible-only keeps them)")
        if not len(faces):
            raise NerfkitError(f"no face of the level set at {level:.4g} is seen by the training views; try a lower "
                               f"--threshold or --no-visible-only")
    if snap:  # onto the half-opaque surface, searched within SNAP_CELLS grid cells
        snapper = half_opacity_snapper(density_fn, SNAP_CELLS * h)
        verts = chunked(snapper, verts, vertex_normals(verts, faces), chunk=16384)
    carved = carve_mesh(run, verts, faces, h, data, log) if carve else None
    if carved is not None:
        verts, faces, carved = carved
    return verts, faces, {"threshold": level, "threshold_rule": rule, "faces_of_level_set": n_level_set,
                          "visible_only": visible_only, "snapped_to_half_opacity": snap,
                          "carved_to_silhouettes": carved,
                          "occupied_fraction": None if mask is None else float(mask.mean())}
