"""A run's cameras as nerfstudio's transforms.json: OpenGL camera-to-world matrices in the capture's
own coordinates, the lens of each photo at its size on disk (data/nerfstudio.camera_to_json), and
`file_path` / `mask_path` relative to the written file's folder when the photos lie inside it
(write it into the capture folder to get a capture nerfstudio opens), else absolute."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from nerfkit.data.loader import read_capture
from nerfkit.data.nerfstudio import write_nerfstudio
from nerfkit.errors import ConfigError
from nerfkit.export.run import check_out, exports_dir, write_atomic, write_record


def relative_path(path: Path, start: Path) -> str:
    """`path` relative to folder `start` when it lies inside it (the usual capture layout), else
    absolute (POSIX separators): the file still opens wherever it is moved."""
    path, start = Path(path).resolve(), Path(start).resolve()
    return path.relative_to(start).as_posix() if path.is_relative_to(start) else path.as_posix()


def export_cameras(run_dir: Path, out: Path | None = None, split: str | None = None, data: Path | None = None,
                   log=print) -> dict:
    """`nerfkit export cameras`: the frames of `split` (default: the run's training split) as
    transforms.json at `out` (default RUN/exports/cameras.json), with a picture in RUN/exports/."""
    from nerfkit.evaluate import run_data_dir
    from nerfkit.process.plot import plot_cameras
    from nerfkit.train import load_run_config

    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ConfigError(f"{run_dir}: not a run folder (no config.json); pass a folder written by nerfkit train")
    out = check_out(Path(out) if out is not None else run_dir / "exports" / "cameras.json", (".json",))
    t0 = time.perf_counter()
    cfg = load_run_config(run_dir)
    d = cfg.data
    split = split or d.train_split
    cap = read_capture(run_data_dir(run_dir, data), split, d.format, d.masks, d.holdout_every)
    frames = cap.frames(split)
    rows = [{"file_path": relative_path(f.image, out.parent), "transform_matrix": f.c2w,
             "mask_path": relative_path(f.mask, out.parent) if f.mask is not None else None} for f in frames]
    write_atomic(out, lambda tmp: write_nerfstudio(tmp, rows, [f.camera for f in frames],
                                                   extra={"nerfkit": {"run": str(run_dir.resolve()), "split": split}}))
    c2ws = np.stack([f.c2w for f in frames]).astype(np.float64)
    picture = plot_cameras(exports_dir(run_dir) / "cameras.png", c2ws, [f.camera for f in frames],
                           title=f"{out.name}: {len(frames)} cameras of {split}")
    log(f"cameras: {len(frames)} frames of {split} ({cap.format} capture) in nerfstudio's transforms.json layout")
    record = {"kind": "cameras", "file": str(out.resolve()), "split": split, "frames": len(frames),
              "format": "nerfstudio transforms.json", "seconds": round(time.perf_counter() - t0, 2),
              "picture": picture.name, "coordinates": "the capture's own (OpenGL camera-to-world)"}
    write_record(run_dir, "cameras", record)
    return record
