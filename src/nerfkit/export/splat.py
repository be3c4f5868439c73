"""`nerfkit export splat`: a splat run's Gaussians as a file other splat tools open, in the capture's own
coordinates; the format is the --out extension (models/splat/formats: .ply, .spz, .splat, .glb, .gltf, .sog).

The run trains in nerfkit's normalised frame x_n = M x (scene.json's transform, a similarity
s R x + t). The file holds the Gaussians moved by M^-1 (splat/transform.py): centres mapped,
log scales minus log s, rotations turned by R^T (q' = q(R^T) q), and the SH coefficients of bands
1..3 rotated exactly (each band's real-SH rotation matrix), so a viewer that draws the file with
the capture's own cameras sees what nerfkit renders. Only the active Gaussians are written,
with the run's SH degree, or the format's highest where that is lower (.splat: degree 0).

The picture (RUN/exports/splat.png) is the written file read back, moved back into the run's frame and
rendered from the first training camera: the round trip, shown. The record states the file's size and that
render's PSNR against the run's own render of the same view (what the format's quantisation and SH
truncation cost).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tyro

from nerfkit.core.errors import ConfigError
from nerfkit.core.metrics import psnr
from nerfkit.core.viz import save_png
from nerfkit.export.files import check_out, write_atomic
from nerfkit.export.registry import Exporter, check_accepts
from nerfkit.models.splat.formats import FORMATS, read_gaussians, splat_format
from nerfkit.models.splat.gaussians import held_out_gaussians, render_frame
from nerfkit.models.splat.project import LOWPASS_DILATION
from nerfkit.models.splat.transform import invert_similarity, transform_gaussians
from nerfkit.rays.cameras import Camera
from nerfkit.run.folder import RunFolder


def active_gaussians(run) -> dict:
    """The run's Gaussians in use (numpy, gaussians.py's layout, normalised frame), coloured as nerfkit renders a
    view that is no training photo (gaussians.held_out_gaussians)."""
    return held_out_gaussians(run.params, run.aux)


def export_splat(run_dir: Path, out: Path | None = None, overwrite: bool = False, log=print) -> dict:
    """Write RUN's Gaussians to `out` (default RUN/exports/splat.ply) in the capture's coordinates, in the format
    of its extension; refuses to replace a file unless `overwrite` and refuses runs that are not splat runs.
    Returns the record."""
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ConfigError(f"{run_dir}: not a run folder (no config.json); pass a folder written by nerfkit train")
    out = check_out(Path(out) if out is not None else run_dir / "exports" / "splat.ply", tuple(FORMATS), overwrite)
    fmt = splat_format(out)
    t0 = time.perf_counter()
    folder = RunFolder(run_dir)
    run = folder.load()
    check_accepts(EXPORTER, run_dir, run.model.supports, run.model.title)
    gaussians = active_gaussians(run)
    degree = min(run.cfg.splat.sh_degree, fmt.max_sh)
    in_capture = transform_gaussians(gaussians, invert_similarity(run.transform))
    write_atomic(out, lambda tmp: fmt.write(tmp, in_capture, degree))
    seconds = time.perf_counter() - t0
    back = transform_gaussians(read_gaussians(out)[0], run.transform)
    pose = np.asarray(run.scene["train_poses"][0], np.float64)
    camera, background = Camera.from_json(run.scene["camera"]), run.model.background
    shown = render_frame(back, pose, camera, background, degree, depth=False)["rgb"]  # as viewers draw it (0.3 px^2)
    dilation = run.cfg.splat.screen_dilation
    own = render_frame(gaussians, pose, camera, background, run.cfg.splat.sh_degree, depth=False,
                       dilation=dilation)["rgb"]
    picture = folder.exports / "splat.png"
    save_png(picture, shown)
    log(f"splat: {len(gaussians['means'])} Gaussians, SH degree {degree}, {fmt.name}, capture coordinates")
    if dilation != LOWPASS_DILATION:
        log(f"note: the run drew its splats with --screen-dilation {dilation:g} px^2 and viewers draw them with "
            f"{LOWPASS_DILATION:g}: a training photo drawn so is {psnr(own, shown):.1f} dB from the run's own render "
            f"(picture: {picture})")
    record = {"kind": "splat", "file": str(out.resolve()), "format": fmt.name, "opens": fmt.opens,
              "bytes": out.stat().st_size, "gaussians": int(len(gaussians["means"])), "sh_degree": degree,
              "psnr_vs_run": round(float(psnr(own, shown)), 2), "coordinates": "capture (scene.json transform undone)",
              "seconds": round(seconds, 2), "picture": picture.name, "step": run.step}
    folder.write_record("splat", record)
    return record


@dataclass
class ExportSplatArgs:
    """Export a splat run's Gaussians in the capture's own coordinates, as the --out extension says: .ply (the
    Inria 3DGS layout: SuperSplat, gsplat, nerfstudio, Brush, Spark), .spz (Niantic's, about a tenth of the
    .ply's size: Spark, GaussianSplats3D, SuperSplat), .splat (antimatter15's, no view-dependent colour), .glb or
    .gltf (glTF 2.0 with KHR_gaussian_splatting: the PlayCanvas engine), .sog (PlayCanvas's SOG, about a
    twentieth of the .ply's size: SuperSplat, the PlayCanvas engine, Spark). A picture of the file read back goes into
    RUN_DIR/exports/splat.png."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train --preset splat`."""
    out: Path | None = None
    """The file to write: .ply, .spz, .splat, .glb, .gltf or .sog (default: RUN_DIR/exports/splat.ply)."""
    overwrite: bool = False
    """Replace --out if it exists."""

def _wrote(rec: dict) -> str:
    return (f"wrote {rec['file']}: {rec['format']}, {rec['gaussians']} Gaussians, SH degree {rec['sh_degree']}, "
            f"{_size(rec['bytes'])}; read back, {rec['psnr_vs_run']:.1f} dB against the run's render "
            f"({rec['seconds']:.1f} s)")



def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"


def _facts(rec: dict) -> str:
    size = f", {_size(rec['bytes'])}, {rec['psnr_vs_run']:.1f} dB against the run" if "bytes" in rec else ""
    return f"{rec.get('format', 'Inria 3DGS .ply')}: {rec['gaussians']} Gaussians, SH degree {rec['sh_degree']}{size}"


EXPORTER = Exporter(
    name="splat",
    summary="a splat run's Gaussians as .ply, .spz, .splat, glTF or .sog (SuperSplat, Spark, gsplat, PlayCanvas)",
    args=ExportSplatArgs, accepts=lambda supports: supports.gaussians, needs="Gaussians (a run of --preset splat)",
    outputs=("splat.ply", "splat.png"), export=lambda a, given: export_splat(a.run_dir, a.out, overwrite=a.overwrite),
    wrote=_wrote, facts=_facts)
