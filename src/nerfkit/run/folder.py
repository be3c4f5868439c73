"""A run folder, as `nerfkit train` leaves it, and the one way anything reads it.

    RUN/config.json        the resolved Config          RunFolder.config()
    RUN/scene.json         data folder, size, camera, capture transform, training poses
                                                        RunFolder.scene(), RunFolder.data_dir()
    RUN/checkpoints/       msgpack checkpoints          RunFolder.load() -> TrainedRun
    RUN/exports/           one JSON record per export   RunFolder.write_record(), .records()

Every reader (eval, render, view, export, bake, report, experiments) goes through RunFolder, so a
broken or incomplete folder is refused in one place, with one line naming the file and the fix.
The trainer writes these files (training/trainer.py); this layer sits above it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.data.loader import read_capture, scene_cameras
from nerfkit.models.registry import METHODS, build_model
from nerfkit.rays.correction import run_poses
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training.step import init_state, make_optimizer

SCENE_KEYS = ("data_dir", "format", "height", "width", "camera", "transform", "scale", "train_poses")


@dataclass
class TrainedRun:
    """A run's model with its newest (or a chosen) checkpoint's parameters, on the device."""

    run_dir: Path
    cfg: Config
    model: object
    params: dict
    aux: dict
    step: int
    scene: dict | None  # scene.json (None when loaded with scene=False)

    @property
    def transform(self) -> np.ndarray:
        """M [4, 4]: normalised point x_n = M [x, 1] of capture point x (identity for Blender scenes)."""
        return np.asarray(self.scene.get("transform", np.eye(4)), np.float64)

    @property
    def bound(self) -> float:
        """Half-size B of the box [-B, B]^3 exports sample (normalised units): the field's box, or
        the inner ball of an unbounded scene (the contracted far region is not exported)."""
        return float(self.cfg.field.resolved_bound())

    @property
    def refined_poses(self) -> bool:
        """Whether the run learned a pose correction per training photo (--pose-refine on)."""
        return isinstance(self.params, dict) and "cam_pose" in self.params

    def seen_from(self, split: str, poses: np.ndarray, data_dir: Path | None = None) -> np.ndarray:
        """The poses [M, 4, 4] to render the frames of `split` from, given theirs [M, 4, 4] (normalised): these,
        unless the run refined its training poses (rays/correction.run_poses): then the training photos' own
        refined poses for the training split, and for any other the given poses moved with the training rig (the
        training split's given poses are read from data_dir, default the run's)."""
        if not self.refined_poses:
            return np.asarray(poses)
        d = self.cfg.data
        if split == d.train_split:
            return run_poses(self.params, poses)
        cap = read_capture(RunFolder(self.run_dir).data_dir(data_dir), d.train_split, d.format, d.masks,
                           d.holdout_every)
        train = scene_cameras(cap, d.train_split, d.downscale, d.target_width, d.undistort).poses
        try:
            return run_poses(self.params, train, poses)
        except ValueError as e:
            raise ConfigError(f"{RunFolder(self.run_dir).data_dir(data_dir)}: {e} in the training split "
                              f"{d.train_split!r}; use the data the run was trained on") from None


class RunFolder:
    """The files of one run folder (see the module docstring); nothing is read until asked."""

    def __init__(self, path: str | Path):
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"RunFolder({str(self.path)!r})"

    def config_json(self):
        """RUN/config.json's JSON as read, before it is checked as a Config; ConfigError naming the file when
        missing or not JSON (cut short, say)."""
        path = self.path / "config.json"
        if not path.is_file():
            raise ConfigError(f"{path}: missing; is {self.path} a nerfkit run folder?")
        try:
            return json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
            raise ConfigError(f"{path}: not valid JSON ({e}); restore it or start a new run") from None

    def config(self) -> Config:
        """RUN/config.json as a Config; ConfigError naming the file when missing or broken."""
        path = self.path / "config.json"
        raw = self.config_json()
        try:
            cfg = Config.from_dict(raw)
        except ConfigError as e:
            raise ConfigError(f"{path}: {e}") from None
        if cfg.field.kind not in METHODS:
            raise ConfigError(f"{path}: field.kind must be one of {', '.join(METHODS)} (got {cfg.field.kind!r}); "
                              f"restore it or start a new run")
        return cfg

    def scene(self) -> dict:
        """RUN/scene.json (what the run was trained on: data folder, image size, camera, capture
        transform, training poses); NerfkitError naming the file when missing, unreadable or incomplete."""
        path = self.path / "scene.json"
        try:
            scene = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise NerfkitError(f"{path}: missing; is {self.path} a complete nerfkit run folder? (train it again, "
                               f"or copy the file back)") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
            raise NerfkitError(f"{path}: unreadable ({type(e).__name__}); restore it from a copy or train "
                               f"again") from None
        missing = [k for k in SCENE_KEYS if not isinstance(scene, dict) or k not in scene]
        if missing:
            raise NerfkitError(f"{path}: not a nerfkit scene record (missing {', '.join(missing)}); restore it "
                               f"from a copy or train again")
        return scene

    def data_dir(self, given: Path | None = None) -> Path:
        """The data folder of the run: the one given, else the one it was trained on (scene.json)."""
        if given is not None:
            return Path(given)
        path = Path(self.scene()["data_dir"])
        if not path.is_dir():
            raise ConfigError(f"{path}: the data folder this run was trained on is gone; pass --data DIR (where "
                              f"the capture is now)")
        return path

    def load(self, checkpoint: Path | None = None, scene: bool = True) -> TrainedRun:
        """The model and the parameters of the newest checkpoint (or of `checkpoint`), as device
        arrays (export and render functions close over them in jit); scene.json too unless `scene`
        is False (evaluation with an explicit --data does not need it)."""
        if not (self.path / "config.json").is_file():
            raise ConfigError(f"{self.path}: not a run folder (no config.json); pass a folder written by "
                              f"nerfkit train")
        cfg = self.config()
        model = build_model(cfg)
        optimizer, _ = make_optimizer(cfg, model)
        path = ckpt_lib.latest_checkpoint(self.path / "checkpoints") if checkpoint is None else Path(checkpoint)
        if path is None:
            raise NerfkitError(f"{self.path / 'checkpoints'}: no checkpoint yet; train first")
        # Only the structure is needed (the checkpoint supplies the values): eval_shape traces the
        # initialisers without running them, which saves compiling ~40 small random programs (~3 s).
        shapes = jax.eval_shape(lambda: init_state(model, optimizer, cfg.train.seed))
        target = jax.tree_util.tree_map(lambda s: np.zeros(s.shape, s.dtype), shapes)
        step, state = ckpt_lib.restore_checkpoint(path, target, cfg.to_dict()["field"])
        params, aux = jax.device_put((state["params"], state["aux"]))  # (jnp.asarray compiles a copy per shape)
        return TrainedRun(self.path, cfg, model, params, aux, step, self.scene() if scene else None)

    @property
    def exports(self) -> Path:
        """RUN/exports/ (made on first use)."""
        path = self.path / "exports"
        path.mkdir(parents=True, exist_ok=True)
        return path

    def write_record(self, kind: str, record: dict) -> Path:
        """RUN/exports/export_<kind>.json: what was exported where (the report reads it)."""
        path = self.exports / f"export_{kind}.json"
        path.write_text(json.dumps(record, indent=2))
        return path

    def records(self) -> dict[str, dict]:
        """The export records of the run (RUN/exports/export_<kind>.json), by kind, in name order: those that
        exist and parse as a JSON object."""
        out = {}
        for path in sorted((self.path / "exports").glob("export_*.json")):
            try:
                rec = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if isinstance(rec, dict):
                out[path.stem.removeprefix("export_")] = rec
        return out
