"""A trained field as a coloured point cloud: rendered depth of chosen views, back-projected and fused.

For each pixel of a rendered view with opacity a = sum_i w_i >= min_opacity, the point is

    x = o + t_bar d,   t_bar = sum_i w_i t_i / a     (the expected termination depth)

on the pixel's ray o + t d, coloured with the surface colour un-composited from the
background b: c = (rgb - (1 - a) b) / a. Points of all views are fused by voxel
downsampling: one point per occupied voxel of size v, the mean of its points and colours.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tyro

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.export.files import check_out, to_capture, write_atomic
from nerfkit.export.pictures import pointcloud_picture
from nerfkit.export.registry import Exporter
from nerfkit.export.splat import active_gaussians
from nerfkit.export.visibility import render_views, view_points
from nerfkit.models.splat.project import SH_C0
from nerfkit.render.images import check_chunk, check_every
from nerfkit.run.folder import RunFolder

VOXELS_PER_BOX = 512  # default voxel: the box's side / this


def voxel_downsample(points: np.ndarray, colors: np.ndarray, voxel: float):
    """One point per voxel of side `voxel` (<= 0: unchanged): the mean point and colour of each
    occupied voxel floor(x / voxel). Returns points [M, 3], colours [M, 3]."""
    if voxel <= 0 or not len(points):
        return points, colors
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    m = len(counts)
    out_p = np.zeros((m, 3), np.float64)
    out_c = np.zeros((m, 3), np.float64)
    np.add.at(out_p, inverse, points)
    np.add.at(out_c, inverse, colors)
    return (out_p / counts[:, None]).astype(np.float32), (out_c / counts[:, None]).astype(np.float32)


MAX_VOXELS_PER_BOX = 2**20  # finer than this is no downsampling at all (and its voxel keys would overflow)


def check_voxel(voxel_size: float | None, voxel_n: float, bound: float, scale: float) -> None:
    """ConfigError for a --voxel-size (capture units; voxel_n: normalised) that is not 0 and either spans more
    than the whole box (2 bound, normalised) or is finer than the box / MAX_VOXELS_PER_BOX."""
    if voxel_size is None or voxel_size == 0:
        return
    box = 2.0 * bound / scale  # the box's side in capture units
    if not voxel_n <= 2.0 * bound:
        raise ConfigError(f"--voxel-size {voxel_size:g} is larger than the scene's box ({box:.4g} capture units "
                          f"a side): every point would merge into one; give a smaller one (default "
                          f"{box / VOXELS_PER_BOX:.3g})")
    if not voxel_n >= 2.0 * bound / MAX_VOXELS_PER_BOX:
        raise ConfigError(f"--voxel-size {voxel_size:g} is under a millionth of the scene's box ({box:.4g} capture "
                          f"units a side); pass --voxel-size 0 to keep every point")


def write_pointcloud(out: Path, points: np.ndarray, colors_u8: np.ndarray) -> None:
    """A binary PLY of coloured points (trimesh)."""
    import trimesh

    pc = trimesh.PointCloud(points, colors=colors_u8)
    write_atomic(Path(out), lambda tmp: pc.export(tmp))


def export_pointcloud(run_dir: Path, out: Path | None = None, split: str | None = None, every: int | None = None,
                      min_opacity: float = 0.9, voxel_size: float | None = None, data: Path | None = None,
                      chunk: int | None = None, progress: bool = True, log=print,
                      overwrite: bool = False) -> dict:
    """`nerfkit export pointcloud`: fuse the depth of every `every`-th view of `split` (default:
    the run's training split) into RUN/exports/pointcloud.ply (or `out`), in the capture's units."""
    check_every(every)
    if not 0.0 < min_opacity <= 1.0:
        raise ConfigError(f"--min-opacity must be in (0, 1] (got {min_opacity})")
    if voxel_size is not None and not 0 <= voxel_size < float("inf"):
        raise ConfigError(f"--voxel-size must be >= 0 and finite (0: no downsampling; got {voxel_size})")
    check_chunk(chunk)
    out = check_out(Path(out) if out is not None else Path(run_dir) / "exports" / "pointcloud.ply", (".ply",), overwrite)
    t0 = time.perf_counter()
    run = RunFolder(run_dir).load()
    scale = float(np.cbrt(np.linalg.det(run.transform[:3, :3])))  # capture -> normalised lengths
    voxel_n = 2.0 * run.bound / VOXELS_PER_BOX if voxel_size is None else voxel_size * scale
    check_voxel(voxel_size, voxel_n, run.bound, scale)
    if run.model.supports.gaussians:
        given = [f for f, v in (("--split", split), ("--every", every), ("--data", data), ("--chunk", chunk))
                 if v is not None]
        if given:
            raise ConfigError(f"{given[0]} has no effect on a splat run (its point cloud is the Gaussians' centres, "
                              f"no views are rendered); drop it")
        return splat_centres(run, out, min_opacity, voxel_n, scale, t0, log)
    views = render_views(run, split, every, data, chunk, progress=progress)
    background = np.asarray(run.model.background, np.float32)
    pts, cols = zip(*(view_points(views, k, background, min_opacity) for k in range(len(views.c2w))))
    split, n_views = views.split, len(views.c2w)
    pts, cols = np.concatenate(pts), np.concatenate(cols)
    if not len(pts):
        raise NerfkitError(f"no pixel of the {n_views} rendered views of {split} reaches opacity {min_opacity:g}; "
                           f"try a lower --min-opacity")
    n_raw = len(pts)
    n_pts, picture = write_cloud(run, out, pts, cols, voxel_n, f"points from {n_views} views")
    log(f"pointcloud: {n_raw} pixels with opacity >= {min_opacity:g} in {n_views} views of {split} "
        f"-> {n_pts} points (voxel {voxel_n / scale:.4g} capture units)")
    record = {"kind": "pointcloud", "file": str(out.resolve()), "step": run.step, "split": split, "every": views.every,
              "views": n_views, "min_opacity": min_opacity, "pixels": n_raw, "points": n_pts,
              "voxel_size": voxel_n / scale, "seconds": round(time.perf_counter() - t0, 2), "picture": picture.name,
              "coordinates": "the capture's own (pose normalisation undone)"}
    RunFolder(run.run_dir).write_record("pointcloud", record)
    return record


def write_cloud(run, out: Path, pts: np.ndarray, cols: np.ndarray, voxel_n: float, what: str) -> tuple[int, Path]:
    """Voxel-downsample the points [N, 3] (normalised frame) and colours [N, 3] in [0, 1], write them to `out` in
    the capture's coordinates, and draw the run's exports/pointcloud.png titled "{out.name}: {n} {what}".
    Returns (n, the picture's path)."""
    pts, cols = voxel_downsample(pts, cols, voxel_n)
    colors_u8 = (cols * 255 + 0.5).astype(np.uint8)
    write_pointcloud(out, to_capture(pts, run.transform), colors_u8)
    picture = pointcloud_picture(run.run_dir / "exports" / "pointcloud.png", pts, colors_u8,
                                 f"{out.name}: {len(pts)} {what} (step {run.step})")
    return len(pts), picture


def splat_centres(run, out: Path, min_opacity: float, voxel_n: float, scale: float, t0: float, log=print) -> dict:
    """The point cloud of a splat run: the centres of its Gaussians of opacity >= min_opacity, coloured by
    their view-independent (degree-0) colour SH_C0 f_dc + 0.5, voxel-downsampled like the fused clouds."""
    g = active_gaussians(run)
    keep = 1.0 / (1.0 + np.exp(-g["opacity"].astype(np.float64))) >= min_opacity
    if not keep.any():
        raise NerfkitError(f"no Gaussian of {run.run_dir} reaches opacity {min_opacity:g}; try a lower --min-opacity")
    pts = g["means"][keep].astype(np.float64)
    cols = np.clip(SH_C0 * g["sh_dc"][keep, 0] + 0.5, 0.0, 1.0)
    n_raw = len(pts)
    n_pts, picture = write_cloud(run, out, pts, cols, voxel_n, "Gaussian centres")
    log(f"pointcloud: {n_raw} of {len(keep)} Gaussian centres with opacity >= {min_opacity:g} -> {n_pts} points "
        f"(voxel {voxel_n / scale:.4g} capture units)")
    record = {"kind": "pointcloud", "file": str(out.resolve()), "step": run.step, "source": "Gaussian centres",
              "views": 0, "min_opacity": min_opacity, "gaussians": n_raw, "points": n_pts,
              "voxel_size": voxel_n / scale, "seconds": round(time.perf_counter() - t0, 2), "picture": picture.name,
              "coordinates": "the capture's own (pose normalisation undone)"}
    RunFolder(run.run_dir).write_record("pointcloud", record)
    return record


@dataclass
class ExportPointcloudArgs:
    """Export a coloured point cloud (PLY): the rendered depth of every K-th view of a split, back-projected,
    fused and voxel-downsampled, in the capture's own coordinates."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    out: Path | None = None
    """PLY file (default: RUN_DIR/exports/pointcloud.ply)."""
    split: str | None = None
    """Views to render (default: the run's training split)."""
    every: int | None = None
    """Use every K-th view (default: about 32 views, evenly spaced)."""
    min_opacity: float = 0.9
    """Keep pixels at least this opaque."""
    voxel_size: float | None = None
    """Fuse points into voxels of this size, in the capture's units (default: the box side / 512; 0: keep all)."""
    data: Path | None = None
    """The data folder; default: the one the run was trained on."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""
    progress: bool = True
    """Show progress bars."""
    overwrite: bool = False
    """Replace --out if it exists."""

def _export(a: ExportPointcloudArgs, given: set[str]) -> dict:
    return export_pointcloud(a.run_dir, a.out, a.split, a.every, a.min_opacity, a.voxel_size, a.data, a.chunk,
                             progress=a.progress, overwrite=a.overwrite)


def _facts(rec: dict) -> str:
    return ("{points} points ({source})" if "source" in rec else "{points} points from {views} views").format(**rec)


EXPORTER = Exporter(
    name="pointcloud", summary="a coloured point cloud (.ply): rendered depth back-projected, or a splat run's centres",
    args=ExportPointcloudArgs, accepts=lambda supports: supports.mesh or supports.gaussians,
    needs="a density field or Gaussians", outputs=("pointcloud.ply", "pointcloud.png"), export=_export,
    wrote=lambda rec: f"wrote {rec['file']}: {rec['points']} points ({rec['seconds']:.1f} s)", facts=_facts)
