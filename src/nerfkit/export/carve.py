"""Silhouette carving: keep an exported mesh inside the visual hull of the training silhouettes.

A capture with masks (or, like the Blender scenes, with an alpha channel) says where the object
is not: a point whose projection falls on the background of a training photo lies outside
the object. With the silhouette S_k of view k as its pixels of alpha_k > 1/2, the hull is

    H = { x : pi_k(x) + (a, b) in S_k for (a, b) in {(0, 0), (+-m, +-m)}, all but at most t of the
              views k whose image x falls in },

pi_k the projection of view k (its lens included), a point in S_k when the pixel it falls in
is, and m a margin in pixels (MARGIN_PX = 1/2): a per-pixel silhouette places its edge only to
within half a pixel, and a surface point on a contour falls on a pixel covered less than half
about half the time, so the carved surface is kept half a pixel inside the edge. One mask may
be wrong (TOLERANCE_VIEWS, t = 1): maryrose's hand-drawn mask of IMG_9683 leaves out the
tankard's open mouth, and with t = 0 the inside seen through it, and half the handle, went.

The field's level set overshoots H where the object turns away from the cameras (rounded or
fattened contours of about a pixel). Each vertex x outside H moves in, along its inward normal
or, where that does not lead in (a thin part seen edge-on, whose rough normal leads out of it),
along one of the 26 directions e_j to a cube's neighbours:

    x' = x - s n,    s = the first of delta, 2 delta, ..., S with x - s n in H;   else
    x' = x + s e_j,  the first s (then the lowest j) with x + s e_j in H.

A vertex that no such step brings into H is surface where some training photo shows
background through it (a film spanning a gap, a floater): the faces that use it are dropped.
"""

from __future__ import annotations

import numpy as np

from nerfkit.data.images import area_downscale, read_masked
from nerfkit.data.loader import read_capture, scene_cameras
from nerfkit.rays.cameras import Camera, project_points
from nerfkit.run.folder import RunFolder

MARGIN_PX = 0.5
TOLERANCE_VIEWS = 1


def outside_count(pts: np.ndarray, poses: np.ndarray, cameras: list[Camera], silhouettes: list[np.ndarray],
                  margin: float = 0.0) -> np.ndarray:
    """int [P]: for points [P, 3], the number of views that see them in the image off the silhouette.

    poses [V, 4, 4] camera-to-world (OpenGL), cameras at the size of silhouettes [V] (each bool
    [H, W], alpha > 1/2); a point is off silhouette k when the pixel it falls in is not in it, or,
    with margin m > 0, when any of the pixels of (u, v) and (u +- m, v +- m) in the image is not."""
    out = np.zeros(len(pts), np.int32)
    offsets = [(0.0, 0.0)] + ([(a * margin, b * margin) for a in (-1, 1) for b in (-1, 1)] if margin > 0 else [])
    for pose, cam, sil in zip(poses, cameras, silhouettes):
        u0, v0, front = project_points(pts, pose, cam)
        h, w = sil.shape
        seen = front & (u0 >= 0) & (u0 < w) & (v0 >= 0) & (v0 < h)
        off = np.zeros(len(pts), bool)
        for du, dv in offsets:
            u, v = u0 + du, v0 + dv
            inside = seen & (u >= 0) & (u < w) & (v >= 0) & (v < h)
            iu = np.clip(np.floor(np.where(inside, u, 0)).astype(np.int64), 0, w - 1)
            iv = np.clip(np.floor(np.where(inside, v, 0)).astype(np.int64), 0, h - 1)
            off |= inside & ~sil[iv, iu]
        out += off
    return out


def used_vertices(verts: np.ndarray, faces: np.ndarray):
    """(verts [V', 3], faces [F, 3]): only the vertices the faces use, the faces renumbered."""
    used, inverse = np.unique(faces, return_inverse=True)
    return verts[used], inverse.reshape(faces.shape)


def cube_directions() -> np.ndarray:
    """float [26, 3]: the unit vectors towards the 26 neighbours of a cube's centre."""
    d = np.stack(np.meshgrid(*[np.array([-1.0, 0.0, 1.0])] * 3, indexing="ij"), -1).reshape(-1, 3)
    d = d[np.any(d != 0, axis=1)]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def first_inside(verts: np.ndarray, dirs: np.ndarray, delta: float, max_steps: int, inside) -> np.ndarray:
    """float [P, 3]: for points [P, 3] and candidate unit directions [P, K, 3], the first of
    x + s delta dirs_k (s = 1..max_steps, ties to the lower k) that `inside` (points [M, 3] -> bool [M])
    accepts; NaN where none is."""
    out = np.full(verts.shape, np.nan)
    todo = np.arange(len(verts))
    k = dirs.shape[1]
    for step in range(1, max_steps + 1):
        if not len(todo):
            break
        trial = verts[todo, None, :] + step * delta * dirs[todo]
        ok = inside(trial.reshape(-1, 3)).reshape(len(todo), k)
        hit = ok.any(axis=1)
        out[todo[hit]] = trial[hit, np.argmax(ok[hit], axis=1)]
        todo = todo[~hit]
    return out


def carve(verts: np.ndarray, normals: np.ndarray, faces: np.ndarray, poses: np.ndarray, cameras: list[Camera],
          silhouettes: list[np.ndarray], delta: float, max_steps: int, margin: float = MARGIN_PX,
          tolerance: int = TOLERANCE_VIEWS):
    """Move the vertices [V, 3] outside the visual hull into it (module docstring), in steps of delta up
    to S = max_steps delta: along the inward normal -n (normals [V, 3], unit), or where that does not
    lead in, along the nearest of the 26 cube directions; drop the faces [F, 3] that use a vertex no
    such step brings in. tolerance: how many views may put a point off their silhouette (t of H).
    Returns (verts [V', 3], faces [F', 3], stats dict)."""
    verts = np.array(verts, np.float64, copy=True)

    def inside(p):
        return outside_count(p, poses, cameras, silhouettes, margin) <= tolerance

    todo = np.flatnonzero(~inside(verts))
    moved = first_inside(verts[todo], -np.asarray(normals, np.float64)[todo, None, :], delta, max_steps, inside)
    ok = ~np.isnan(moved[:, 0])
    verts[todo[ok]] = moved[ok]
    along_normal = int(ok.sum())
    rest = todo[~ok]
    moved = first_inside(verts[rest], np.broadcast_to(cube_directions(), (len(rest), 26, 3)), delta, max_steps,
                         inside)
    ok = ~np.isnan(moved[:, 0])
    verts[rest[ok]] = moved[ok]
    absent = np.zeros(len(verts), bool)
    absent[rest[~ok]] = True
    keep = ~absent[faces].any(axis=1)
    out_verts, out_faces = used_vertices(verts, faces[keep])
    stats = {"outside": int(len(todo)), "moved_along_normal": along_normal, "moved_otherwise": int(ok.sum()),
             "absent": int(absent.sum()), "dropped_faces": int((~keep).sum()), "step": float(delta),
             "max_move": float(max_steps * delta), "margin_px": float(margin),
             "tolerance_views": int(tolerance)}
    return out_verts.astype(np.float32), out_faces, stats


def pixel_footprint(poses: np.ndarray, cameras: list[Camera]) -> float:
    """The median over views of |o_k| / f_k: one pixel's size at the origin (the scene's centre)."""
    return float(np.median([np.linalg.norm(p[:3, 3]) / c.fx for p, c in zip(poses, cameras)]))


def training_silhouettes(run, data=None, split: str | None = None):
    """(poses [V, 4, 4] normalised, cameras, silhouettes: bool [H, W], alpha > 1/2) of the run's training
    views (or those of `split`) at the photos' own size (shrunk as the loader shrinks large photos), or
    None when the capture has neither masks nor an alpha channel."""
    d = run.cfg.data
    split = split or d.train_split
    cap = read_capture(RunFolder(run.run_dir).data_dir(data), split, d.format, d.masks, d.holdout_every)
    frames = cap.frames(split)
    if not (cap.alpha or any(f.mask is not None for f in frames)):
        return None
    sel = scene_cameras(cap, split)
    silhouettes = []
    for f in frames:
        _, a = read_masked(f.image, f.mask, (f.camera.width, f.camera.height))
        silhouettes.append(area_downscale(a, sel.factor) > 0.5)
    return run.seen_from(split, sel.poses, data).astype(np.float64), sel.cameras, silhouettes
