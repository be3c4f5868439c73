"""What a Trainer settles before its first step (trainer.py): whether the run folder may be written (an earlier
run's files are refused unless resumed or overwritten), and the training and validation frames of the capture,
with the config resolved from them (resolve.py).
"""

from __future__ import annotations

import copy
import dataclasses
import shutil
from pathlib import Path

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError, DataError, NerfkitError
from nerfkit.data.capture import Capture, SceneData
from nerfkit.data.formats import registry
from nerfkit.data.loader import load_frames, read_capture
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training.flags import refuse_family_switch, refuse_unused
from nerfkit.training.resolve import default_splits, lens_plan, resolve_config, wants_ndc

# What a run folder holds (train.py's docstring; eval, render, export and report add the rest): a fresh
# run refuses a folder holding any of them unless told to overwrite, and then removes exactly these.
RUN_FILES = ("config.json", "scene.json", "metrics.jsonl", "val_metrics.jsonl", "plots", "val", "checkpoints",
             "report.html", "renders", "exports", "eval_*")


def run_files(run_dir: Path) -> list[Path]:
    """The files and folders of an earlier run in run_dir (RUN_FILES), sorted."""
    run_dir = Path(run_dir)
    return sorted({p for pattern in RUN_FILES for p in run_dir.glob(pattern)})


def clear_run(run_dir: Path) -> None:
    """Remove an earlier run's files (run_files) from run_dir; anything else in it stays."""
    for p in run_files(run_dir):
        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()


def refuse_unfit_run_folder(run_dir: Path, flag: str = "--out") -> None:
    """ConfigError when run_dir is a file, or a capture's folder (a run written there, or --overwrite clearing
    it, would mix with or remove the capture's files: its val/ photos share a name with a run's val/)."""
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise ConfigError(f"{flag} {run_dir}: is a file; name a folder for the run")
    fmt = registry.holds_capture(run_dir)
    if fmt is not None:
        raise ConfigError(f"{flag} {run_dir}: holds a capture ({fmt.LOOKS_FOR}); write the run to a folder of its "
                          f"own, such as {run_dir / 'run'}")


def refuse_earlier_run(run_dir: Path, resume: bool, overwrite: bool) -> bool:
    """Whether a fresh run must first remove an earlier run's files from run_dir (True only with `overwrite`).

    ConfigError for --resume with --overwrite; NerfkitError when run_dir holds an earlier run's files and
    neither --resume nor --overwrite says what to do with them."""
    if resume and overwrite:
        raise ConfigError("--resume and --overwrite: pick one (continue the run, or start it again from scratch)")
    old = [] if resume else run_files(run_dir)
    if old and not overwrite:
        if ckpt_lib.list_checkpoints(run_dir / "checkpoints"):
            raise NerfkitError(f"{run_dir}: already holds a run; pass --resume to continue it, --overwrite "
                               f"to start it again (its files are removed) or pick a new --out")
        raise NerfkitError(f"{run_dir}: holds an earlier run's files ({', '.join(p.name for p in old[:4])}"
                           f"{', ...' if len(old) > 4 else ''}) but no checkpoint; pass --overwrite to remove "
                           f"them and start again, or pick a new --out")
    return bool(old)


def refuse_spent_steps(run_dir: Path, max_steps: int) -> None:
    """ConfigError when a run resumed with --max-steps N already holds a checkpoint of step >= N: nothing would
    train, and the run's config.json would be rewritten with the smaller budget."""
    last = ckpt_lib.latest_checkpoint(Path(run_dir) / "checkpoints")
    if last is not None and (step := ckpt_lib.checkpoint_step(last)) >= max_steps:
        raise ConfigError(f"--max-steps {max_steps}: the run in {run_dir} is already at step {step}, so nothing "
                          f"would train; pass a --max-steps above {step} to go on")


def refuse_given(data_dir: Path, cfg: Config, given: dict[str, str], preset: str | None, resume: bool) -> None:
    """ConfigError for the first setting the user gave (`given`: setting -> the flag as typed) that the model or
    this capture will not read, or a --kind that leaves the preset's family (flags.py); `preset` names where
    the model came from in the message. The CLI calls it before it builds the Trainer."""
    where = f"--preset {preset}" if preset and not resume else "this run's model"
    refuse_family_switch(cfg, given, None if resume else preset)
    refuse_unused(cfg, given, where)
    if given:
        d = cfg.data
        spec_train, spec_val = default_splits(cfg)
        capture = read_capture(data_dir, f"{spec_train},{spec_val}", d.format, d.masks, d.holdout_every)
        refuse_unused(cfg, given, where, capture)


def load_splits(data_dir: Path, cfg: Config, progress: bool, say) -> tuple[Capture, SceneData, SceneData, Config]:
    """(capture, training frames, validation frames, cfg resolved from them) of the capture in data_dir.

    The splits are cfg's (default: the capture's train split, and val, else test).
    Validation images must have the training images' size (except multiscale data). `say` gets a line
    describing the data, and resolve_config's lines."""
    d = cfg.data
    spec_train, spec_val = default_splits(cfg)
    capture = read_capture(data_dir, f"{spec_train},{spec_val}", d.format, d.masks, d.holdout_every)
    spec_train, spec_val = default_splits(cfg, list(capture.splits))
    cfg = copy.deepcopy(cfg)
    d = cfg.data
    d.undistort, lens_note = lens_plan(cfg, capture, f"{spec_train},{spec_val}")
    load = dict(downscale=d.downscale, target_width=d.target_width, background=d.background, progress=progress,
                undistort=d.undistort)
    train_data = load_frames(capture, spec_train, **load)
    val_data = load_frames(capture, spec_val, **load)
    if not capture.levels and ((val_data.height, val_data.width) != (train_data.height, train_data.width)):
        raise NerfkitError(f"{data_dir}: validation images ({val_data.width}x{val_data.height}) "
                           f"differ in size from training images ({train_data.width}x{train_data.height})")
    td = train_data
    say(f"data: {capture.format} capture {data_dir}: {len(td)} training ({spec_train}) and "
        f"{len(val_data)} validation ({spec_val}) images at {td.width}x{td.height}"
        f"{', masks on' if td.has_masks else ''}")
    if lens_note:
        say(lens_note + (f" to a {td.width}x{td.height} pinhole camera" if d.undistort else ""))
    if capture.points is None and wants_ndc(cfg, capture, td):  # the NDC's near plane comes from points
        capture = with_triangulated_points(capture, spec_train, say)
    cfg = resolve_config(cfg, capture, td, log=say)
    cfg.data.train_split, cfg.data.val_split = spec_train, spec_val
    return capture, train_data, val_data, cfg


def with_triangulated_points(capture: Capture, spec_train: str, say) -> Capture:
    """The capture with points triangulated from its training photos (`spec_train`: held-out photos are not
    used) at their given poses (process/triangulate.py; cached per photos and poses). A capture where
    none can be triangulated comes back as it was, with a line saying so (the model then starts as it
    would without points, or refuses --init-points sfm)."""
    from nerfkit.process.triangulate import cached_triangulation  # deferred: pycolmap and trimesh load in 0.5 s

    frames = capture.frames(spec_train)
    try:
        tri, ply = cached_triangulation(frames, say)
    except RuntimeError as e:
        say(f"points: none triangulated ({e})")
        return capture
    except OSError as e:
        raise DataError(f"{capture.root}: triangulating points of the training photos failed: {e}") from None
    return dataclasses.replace(capture, points=tri.points, point_colors=tri.colors,
                               points_file=str(ply) if ply is not None else "triangulated.ply")
