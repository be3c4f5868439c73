"""`nerfkit export splat`: a splat run's Gaussians as an Inria-layout .ply in the capture's own coordinates.

The run trains in nerfkit's normalised frame x_n = M x (scene.json's transform, a similarity
s R x + t). The file holds the Gaussians moved by M^-1 (splat/transform.py): centres mapped,
log scales minus log s, rotations turned by R^T (q' = q(R^T) q), and the SH coefficients of bands
1..3 rotated exactly (each band's real-SH rotation matrix), so a viewer that draws the file with
the capture's own cameras sees what nerfkit renders. Only the active Gaussians are written,
with the run's SH degree (f_rest_* count 3 x (0, 3, 8 or 15)).

The picture (RUN/exports/splat.png) is the written file read back with plyfile, moved back into
the run's frame and rendered from the first training camera: the round trip, shown.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tyro

from nerfkit.core.errors import ConfigError
from nerfkit.core.viz import save_png
from nerfkit.export.files import check_out, write_atomic
from nerfkit.export.registry import Exporter, check_accepts
from nerfkit.models.splat.gaussians import held_out_gaussians, render
from nerfkit.models.splat.ply import export_ply, import_ply
from nerfkit.models.splat.transform import invert_similarity
from nerfkit.rays.cameras import Camera
from nerfkit.run.folder import RunFolder


def active_gaussians(run) -> dict:
    """The run's Gaussians in use (numpy, gaussians.py's layout, normalised frame), coloured as nerfkit renders a
    view that is no training photo (gaussians.held_out_gaussians)."""
    return held_out_gaussians(run.params, run.aux)


def export_splat(run_dir: Path, out: Path | None = None, overwrite: bool = False, log=print) -> dict:
    """Write RUN's Gaussians to `out` (default RUN/exports/splat.ply) in the capture's coordinates; refuses
    to replace a file unless `overwrite` and refuses runs that are not splat runs. Returns the record."""
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ConfigError(f"{run_dir}: not a run folder (no config.json); pass a folder written by nerfkit train")
    out = check_out(Path(out) if out is not None else run_dir / "exports" / "splat.ply", (".ply",), overwrite)
    t0 = time.perf_counter()
    folder = RunFolder(run_dir)
    run = folder.load()
    check_accepts(EXPORTER, run_dir, run.model.supports, run.model.title)
    gaussians = active_gaussians(run)
    degree = run.cfg.splat.sh_degree
    to_capture = invert_similarity(run.transform)
    write_atomic(out, lambda tmp: export_ply(tmp, gaussians, transform=to_capture, sh_degree=degree))
    back = import_ply(out, transform=run.transform)
    pose = np.asarray(run.scene["train_poses"][0], np.float64)
    background = run.model.background
    picture = folder.exports / "splat.png"
    save_png(picture, np.clip(render(back, pose, Camera.from_json(run.scene["camera"]), background, degree)["rgb"], 0, 1))
    log(f"splat: {len(gaussians['means'])} Gaussians, SH degree {degree}, Inria .ply layout, capture coordinates")
    record = {"kind": "splat", "file": str(out.resolve()), "gaussians": int(len(gaussians["means"])),
              "sh_degree": degree, "coordinates": "capture (scene.json transform undone)",
              "layout": "Inria 3DGS .ply (x y z nx ny nz f_dc_* f_rest_* opacity scale_* rot_*)",
              "seconds": round(time.perf_counter() - t0, 2), "picture": picture.name, "step": run.step}
    folder.write_record("splat", record)
    return record


@dataclass
class ExportSplatArgs:
    """Export a splat run's Gaussians as a .ply in the Inria 3DGS layout (what SuperSplat, gsplat, nerfstudio and
    other splat viewers open), in the capture's own coordinates; a picture of the file read back goes into
    RUN_DIR/exports/splat.png."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train --preset splat`."""
    out: Path | None = None
    """PLY file (default: RUN_DIR/exports/splat.ply)."""
    overwrite: bool = False
    """Replace --out if it exists."""

def _wrote(rec: dict) -> str:
    return f"wrote {rec['file']}: {rec['gaussians']} Gaussians, SH degree {rec['sh_degree']} ({rec['seconds']:.1f} s)"


EXPORTER = Exporter(
    name="splat", summary="a splat run's Gaussians as an Inria-layout .ply (SuperSplat, gsplat, nerfstudio)",
    args=ExportSplatArgs, accepts=lambda supports: supports.gaussians, needs="Gaussians (a run of --preset splat)",
    outputs=("splat.ply", "splat.png"), export=lambda a, given: export_splat(a.run_dir, a.out, overwrite=a.overwrite),
    wrote=_wrote, facts="{gaussians} Gaussians, SH degree {sh_degree}, read back and rendered".format_map)
