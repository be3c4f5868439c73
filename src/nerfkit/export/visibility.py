"""What the training cameras saw: rendered depth of chosen views, and per-point visibility tests.

A view is a pinhole camera (K, c2w) with its rendered z-depth d(u, v) = sum_i w_i t_i / a and
opacity a(u, v). A point x with outward normal n projects to pixel (u, v) at depth z (along the viewing axis);
with a tolerance m (a grid cell plus one pixel's footprint at that depth, z / f), x is

    seen      by the view when it is the first surface there and faces the camera at o:
              a >= A_MIN,  |z - d| <= m  and  n . (o - x) > 0.

The mesh export keeps the faces some view sees: no camera sees inside a solid object or under
its base, so the field's density there is arbitrary (measured on the procedural scene: 57% of
the raw level set's vertices lay inside the objects); those surfaces are dropped, not guessed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from nerfkit.data.loader import read_capture, scene_cameras
from nerfkit.rays.cameras import Camera, camera_rays
from nerfkit.render.images import make_renderer
from nerfkit.run.folder import RunFolder

A_MIN = 0.5  # a pixel at least this opaque shows a surface at its depth
DEFAULT_VIEWS = 32  # when no --every is given: about this many views, evenly spaced
# Views are rendered in groups of at least this many pixels, one call each: small views (the fusion's 64 to
# 200 px ones) then fill the renderer's ray slots instead of leaving most of them empty in a view's last rounds.
GROUP_RAYS = 1 << 16


@dataclass
class Views:
    """Rendered views (normalised frame): c2w [V, 4, 4], intrinsics [V, 4] = (fx, fy, cx, cy),
    depth (expected, given a hit) / median depth (where the running opacity reaches half the ray's
    opacity, volume.py) / opacity [V, H, W] (median: None unless asked for), rgb [V, H, W, 3], and the pinhole cameras."""

    c2w: np.ndarray
    intrinsics: np.ndarray
    depth: np.ndarray
    median: np.ndarray | None
    opacity: np.ndarray
    rgb: np.ndarray
    cameras: list[Camera]
    split: str
    every: int


def render_views(run, split: str | None = None, every: int | None = None, data=None, chunk: int | None = None,
                 pinhole: bool = False, progress: bool = False, target: int = DEFAULT_VIEWS,
                 width: int | None = None, median: bool = False) -> Views:
    """Render every `every`-th view of `split` (default: the run's training split; about
    `target` views) at the training resolution, or `width` pixels wide (the same field of view).
    pinhole: drop the lens model (for projecting points with K alone); median: also the median depth."""
    d = run.cfg.data
    split = split or d.train_split
    cap = read_capture(RunFolder(run.run_dir).data_dir(data), split, d.format, d.masks, d.holdout_every)
    sel = scene_cameras(cap, split, d.downscale, d.target_width, d.undistort)
    poses = run.seen_from(split, sel.poses, data)  # refined where the run learned its poses
    every = every or max(1, math.ceil(len(sel.poses) / target))
    ids = list(range(0, len(sel.poses), every))
    cams = [sel.cameras[k].with_size(sel.cameras[k].width, sel.cameras[k].height) if pinhole else sel.cameras[k]
            for k in ids]
    if width is not None and cams and cams[0].width != width:
        cams = [c.scaled(width / c.width, width, round(c.height * width / c.width)) for c in cams]
    renderer = make_renderer(run.model, run.cfg.train.chunk if chunk is None else chunk)
    outs = []
    with tqdm(total=len(ids), desc="render views", unit="view", disable=not progress) as bar:
        for group in _groups(cams):  # positions in ids: several small views per call
            outs += renderer.render_cameras(run.params, run.aux, [poses[ids[j]] for j in group],
                                            [cams[j] for j in group], median)
            bar.update(len(group))
    return Views(np.stack([poses[k] for k in ids]).astype(np.float32),
                 np.array([[c.fx, c.fy, c.cx, c.cy] for c in cams], np.float32),
                 np.stack([o["depth_normalized"] for o in outs]),
                 np.stack([o["depth_median"] for o in outs]) if median else None,
                 np.stack([o["opacity"] for o in outs]),
                 np.stack([o["rgb"] for o in outs]), cams, split, every)


def _groups(cams: list[Camera]) -> list[list[int]]:
    """The positions of cams in consecutive groups of at least GROUP_RAYS pixels (each view whole)."""
    groups, cur, n = [], [], 0
    for j, cam in enumerate(cams):
        cur.append(j)
        n += cam.width * cam.height
        if n >= GROUP_RAYS:
            groups.append(cur)
            cur, n = [], 0
    return groups + ([cur] if cur else [])


def view_points(views: Views, k: int, background: np.ndarray, min_opacity: float):
    """Points [P, 3] (normalised frame) and colours [P, 3] of view k's pixels with opacity >=
    min_opacity: x = o + d_bar dir on each pixel's ray (dir with z = -1 in the camera, so t is
    z-depth), colour un-composited from the background, c = (rgb - (1 - a) b) / a."""
    o, d = camera_rays(views.c2w[k], views.cameras[k])
    a = views.opacity[k].reshape(-1)
    keep = a >= min_opacity
    t = views.depth[k].reshape(-1)[keep]
    pts = o.reshape(-1, 3)[keep] + t[:, None] * d.reshape(-1, 3)[keep]
    rgb = views.rgb[k].reshape(-1, 3)[keep]
    col = (rgb - (1.0 - a[keep, None]) * background) / a[keep, None]
    return pts.astype(np.float32), np.clip(col, 0.0, 1.0).astype(np.float32)


def make_visibility(views: Views, margin: float):
    """A jitted function (x [M, 3], n [M, 3]) -> seen bool [M]: some view sees the surface at x with
    outward normal n (see the module docstring); margin: the tolerance in units of length, to
    which one pixel's footprint z / f is added."""
    c2w = jnp.asarray(views.c2w)
    k = jnp.asarray(views.intrinsics)
    depth, opac = jnp.asarray(views.depth), jnp.asarray(views.opacity)
    h, w = views.depth.shape[1:]

    def one_view(c2w_v, k_v, d_v, a_v, x, n):
        p = (x - c2w_v[:3, 3]) @ c2w_v[:3, :3]  # camera frame (OpenGL: looking down -z)
        z = -p[:, 2]
        zs = jnp.maximum(z, 1e-6)
        u = k_v[0] * p[:, 0] / zs + k_v[2]
        v = -k_v[1] * p[:, 1] / zs + k_v[3]
        inside = (z > 1e-6) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        iu = jnp.clip(jnp.floor(u).astype(jnp.int32), 0, w - 1)
        iv = jnp.clip(jnp.floor(v).astype(jnp.int32), 0, h - 1)
        d, a = d_v[iv, iu], a_v[iv, iu]
        m = margin + z / k_v[0]
        facing = jnp.sum(n * (c2w_v[:3, 3] - x), axis=-1) > 0
        return inside & facing & (a >= A_MIN) & (jnp.abs(z - d) <= m)

    @jax.jit
    def visibility(x, n):
        return jnp.any(jax.vmap(one_view, in_axes=(0, 0, 0, 0, None, None))(c2w, k, depth, opac, x, n), axis=0)

    return visibility
