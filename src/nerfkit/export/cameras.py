"""A run's cameras as nerfstudio's transforms.json: OpenGL camera-to-world matrices in the capture's
own coordinates (where the run refined its poses, --pose-refine on, the poses it renders from:
TrainedRun.seen_from, each training photo's refined pose and the other frames' given poses moved with
the training rig; --poses given writes the capture's own), the lens of each photo at its size on disk
(data/nerfstudio.camera_to_json), `file_path` / `mask_path` relative to the written file's folder when
the photos lie inside it, else absolute, and every frame's split in the run as nerfstudio's
train_filenames / val_filenames / test_filenames (nerfkit's nerfstudio reader and nerfstudio's both
keep those splits)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import tyro

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.data.formats.blender import every_split
from nerfkit.data.formats.nerfstudio import write_nerfstudio
from nerfkit.data.loader import read_capture
from nerfkit.data.normalize import apply_transform, undo_transform
from nerfkit.export.files import check_out, write_atomic
from nerfkit.export.registry import Exporter
from nerfkit.process.plot import plot_cameras
from nerfkit.rays.correction import run_poses
from nerfkit.run.folder import RunFolder


def relative_path(path: Path, start: Path) -> str:
    """`path` relative to folder `start` when it lies inside it (the usual capture layout), else
    absolute (POSIX separators): the file still opens wherever it is moved."""
    path, start = Path(path).resolve(), Path(start).resolve()
    return path.relative_to(start).as_posix() if path.is_relative_to(start) else path.as_posix()


def frame_splits(cap, train_spec: str, val_spec: str) -> list[tuple[object, str]]:
    """Every frame of the capture once, with its split in the run: "train" (trained on), "val" (validated
    on), else the capture's own split name ("test" for the held-out frames)."""
    role = {id(f): "train" for f in cap.frames(train_spec)}
    role.update({id(f): "val" for f in cap.frames(val_spec) if id(f) not in role})
    out, seen = [], set()
    for name, frames in cap.splits.items():
        for f in frames:
            if id(f) not in seen:
                seen.add(id(f))
                out.append((f, role.get(id(f), "test" if name == "all" else name)))
    return out


def seen_poses(folder: RunFolder, cfg, cap, frames: list) -> np.ndarray | None:
    """Capture-frame c2w [M, 4, 4] float64 of `frames` as the run renders them (rays/correction.run_poses, as
    TrainedRun.seen_from): each training photo at its refined pose, any other frame at its given pose moved by the
    similarity that maps the given training poses onto the refined ones; None where the run did not refine its
    poses. With the run's normalisation M, s (scene.json): undo_transform(M, s, run_poses(apply_transform(M, s,
    c2w))); cfg: the run's config."""
    if cfg.train.pose_refine != "on":  # no corrections to read: no checkpoint needed
        return None
    try:
        run = folder.load()
    except NerfkitError as e:
        raise NerfkitError(f"{e} (or pass --poses given: the capture's own poses)") from None
    if not run.refined_poses:
        return None
    m, s = run.transform, float(run.scene["scale"])
    train = cap.frames(cfg.data.train_split)
    index = {id(f): k for k, f in enumerate(train)}
    given = apply_transform(m, s, np.stack([f.c2w for f in train]))
    try:
        seen = run_poses(run.params, given)
    except ValueError as e:
        raise ConfigError(f"{cap.root}: {e} in the training split; use the data the run was trained on, or "
                          f"--poses given") from None
    others = [f for f in frames if id(f) not in index]
    moved = dict(zip(map(id, others), run_poses(run.params, given, apply_transform(
        m, s, np.stack([f.c2w for f in others]))))) if others else {}
    return undo_transform(m, s, np.stack([seen[index[id(f)]] if id(f) in index else moved[id(f)] for f in frames]))


def export_cameras(run_dir: Path, out: Path | None = None, split: str | None = None, data: Path | None = None,
                   log=print, overwrite: bool = False, poses: str = "refined") -> dict:
    """`nerfkit export cameras`: every frame of the capture (or only those of `split`) as transforms.json at
    `out` (default RUN/exports/cameras.json), each listed in nerfstudio's train_filenames / val_filenames /
    test_filenames by its split in the run (frame_splits), with a picture in RUN/exports/. `poses`: "refined"
    (the poses the run renders from: seen_poses, the given ones where it refined none) or "given"."""
    if poses not in ("refined", "given"):
        raise ConfigError(f"--poses {poses!r}: use refined or given")
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ConfigError(f"{run_dir}: not a run folder (no config.json); pass a folder written by nerfkit train")
    out = check_out(Path(out) if out is not None else run_dir / "exports" / "cameras.json", (".json",), overwrite)
    t0 = time.perf_counter()
    folder = RunFolder(run_dir)
    cfg = folder.config()
    d = cfg.data
    root = folder.data_dir(data)
    spec = f"{d.train_split},{d.val_split},{every_split(root)}" + (f",{split}" if split else "")
    cap = read_capture(root, spec, d.format, d.masks, d.holdout_every)
    tagged = frame_splits(cap, d.train_split, d.val_split)
    if split is not None:
        chosen = {id(f) for f in cap.frames(split)}
        tagged = [(f, s) for f, s in tagged if id(f) in chosen]
    frames = [f for f, _ in tagged]
    refined = seen_poses(folder, cfg, cap, frames) if poses == "refined" else None
    c2ws = np.stack([f.c2w for f in frames]).astype(np.float64) if refined is None else refined
    rows = [{"file_path": relative_path(f.image, out.parent), "transform_matrix": c2w,
             "mask_path": relative_path(f.mask, out.parent) if f.mask is not None else None}
            for f, c2w in zip(frames, c2ws)]
    lists = {f"{s}_filenames": [r["file_path"] for r, (_, t) in zip(rows, tagged) if t == s]
             for s in ("train", "val", "test")}
    counts = {s: len(v) for s, v in ((k[:-10], v) for k, v in lists.items()) if v}
    extra = {**{k: v for k, v in lists.items() if v},
             "nerfkit": {"run": str(run_dir.resolve()), "train_split": d.train_split, "val_split": d.val_split}}
    write_atomic(out, lambda tmp: write_nerfstudio(tmp, rows, [f.camera for f in frames], extra=extra))
    what = split or ", ".join(f"{n} {s}" for s, n in counts.items())
    picture = plot_cameras(folder.exports / "cameras.png", c2ws, [f.camera for f in frames],
                           title=f"{out.name}: {len(frames)} cameras ({what})")
    written = ("the refined poses the run renders from (training photos' own; other frames moved with the rig)"
               if refined is not None else "the capture's given poses" +
               ("" if poses == "given" else " (the run refined none)"))
    log(f"cameras: {len(frames)} frames ({what}; {cap.format} capture) in nerfstudio's transforms.json layout, "
        f"{written}")
    record = {"kind": "cameras", "file": str(out.resolve()), "split": split or "all", "splits": counts,
              "frames": len(frames), "format": "nerfstudio transforms.json",
              "seconds": round(time.perf_counter() - t0, 2), "picture": picture.name,
              "coordinates": "the capture's own (OpenGL camera-to-world)",
              "poses": "refined" if refined is not None else "given"}
    folder.write_record("cameras", record)
    return record


@dataclass
class ExportCamerasArgs:
    """Export the run's cameras as nerfstudio's transforms.json (OpenGL camera-to-world in the capture's own
    coordinates, intrinsics and lens at the photos' size, image paths relative to the written file)."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    out: Path | None = None
    """JSON file (default: RUN_DIR/exports/cameras.json)."""
    split: str | None = None
    """Export only these frames, e.g. 'test' (default: every frame, each listed under its split in the run)."""
    data: Path | None = None
    """The data folder; default: the one the run was trained on."""
    poses: Literal["refined", "given"] = "refined"
    """refined: the poses the run renders from (a run trained with --pose-refine on: each training photo's refined
    pose, other frames moved with the rig; else the given ones); given: the capture's own."""
    overwrite: bool = False
    """Replace --out if it exists."""

EXPORTER = Exporter(
    name="cameras", summary="the run's cameras as nerfstudio's transforms.json", args=ExportCamerasArgs,
    accepts=lambda supports: True, needs="cameras", outputs=("cameras.json", "cameras.png"),
    export=lambda a, given: export_cameras(a.run_dir, a.out, a.split, a.data, overwrite=a.overwrite,
                                            poses=a.poses),
    wrote=lambda rec: f"wrote {rec['file']}: {rec['frames']} cameras", facts="{frames} cameras".format_map)
