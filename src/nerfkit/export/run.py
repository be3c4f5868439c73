"""The trained run an export reads, the capture-frame transform, and the records an export leaves
in RUN/exports/ (a JSON record and a picture per kind, which the run report shows)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.errors import ConfigError
from nerfkit.outputs import check_new_file
from nerfkit.train import load_run_scene, load_trained

KINDS = ("mesh", "pointcloud", "cameras", "splat")


@dataclass
class TrainedRun:
    run_dir: Path
    cfg: object
    model: object
    params: dict
    aux: dict
    step: int
    scene: dict

    @property
    def transform(self) -> np.ndarray:
        """M [4, 4]: normalised point x_n = M [x, 1] of capture point x (identity for Blender scenes)."""
        return np.asarray(self.scene.get("transform", np.eye(4)), np.float64)

    @property
    def bound(self) -> float:
        """Half-size B of the box [-B, B]^3 exports sample (normalised units): the field's box, or
        the inner ball of an unbounded scene (the contracted far region is not exported)."""
        return float(self.cfg.field.resolved_bound())


def load_run(run_dir: Path) -> TrainedRun:
    run_dir = Path(run_dir)
    if not (run_dir / "config.json").is_file():
        raise ConfigError(f"{run_dir}: not a run folder (no config.json); pass a folder written by nerfkit train")
    cfg, model, params, aux, step = load_trained(run_dir)
    # Device arrays: export functions close over them in jit (numpy arrays cannot be indexed by tracers).
    params, aux = jax.tree_util.tree_map(jnp.asarray, (params, aux))
    scene = load_run_scene(run_dir)
    return TrainedRun(run_dir, cfg, model, params, aux, step, scene)


def to_capture(points: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """Capture-frame points x = M^-1 [x_n, 1] of normalised points x_n [N, 3] (float64 math)."""
    inv = np.linalg.inv(np.asarray(transform, np.float64))
    return (np.asarray(points, np.float64) @ inv[:3, :3].T + inv[:3, 3]).astype(np.float32)


def check_out(out: Path, suffixes: tuple[str, ...], overwrite: bool = False, flag: str = "--out") -> Path:
    """The output path, checked before any work: a known extension, nothing replaced unless `overwrite`,
    a folder that exists or can be made (made only when the file is written: write_atomic)."""
    out = Path(out)
    if out.suffix.lower() not in suffixes:
        raise ConfigError(f"{flag} {out}: unsupported extension {out.suffix or '(none)'!r}; use "
                          + ", ".join(suffixes))
    if out.is_dir():
        raise ConfigError(f"{flag} {out}: is a folder; name a file such as {out / ('export' + suffixes[0])}")
    return check_new_file(out, overwrite, flag)


def write_atomic(out: Path, write) -> None:
    """Call write(tmp_path) on a temporary file beside `out` (same extension), then rename it over
    `out`, so an interrupted export never leaves a truncated file."""
    tmp = out.with_name(f".{out.stem}.partial{out.suffix}")
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        write(tmp)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)


def exports_dir(run_dir: Path) -> Path:
    path = Path(run_dir) / "exports"
    path.mkdir(parents=True, exist_ok=True)
    return path


def write_record(run_dir: Path, kind: str, record: dict) -> Path:
    """RUN/exports/export_<kind>.json: what was exported where (the report reads it)."""
    path = exports_dir(run_dir) / f"export_{kind}.json"
    path.write_text(json.dumps(record, indent=2))
    return path


def read_records(run_dir: Path) -> dict[str, dict]:
    """The export records of a run, by kind (only those that exist and parse)."""
    out = {}
    for kind in KINDS:
        try:
            out[kind] = json.loads((Path(run_dir) / "exports" / f"export_{kind}.json").read_text())
        except (OSError, ValueError):
            continue
    return out
