"""A toy exporter, as a user would add one (export/registry.py): this module and one line in EXPORTERS.
`nerfkit export toy RUN` writes the run's parameter count and its first training view's render."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np
import tyro

from nerfkit.core.viz import save_png
from nerfkit.export.registry import Exporter
from nerfkit.rays.cameras import Camera
from nerfkit.render.images import make_renderer
from nerfkit.run.folder import RunFolder


@dataclass
class ExportToyArgs:
    """Count the run's parameters; render its first training view."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    scale: float = 1.0
    """Multiplies the count (a flag of the exporter's own)."""


def export_toy(a: ExportToyArgs, given: set[str]) -> dict:
    run = RunFolder(a.run_dir).load()
    count = sum(int(np.size(p)) for p in jax.tree_util.tree_leaves(run.params))
    cam = Camera.from_json(run.scene["camera"])
    rgb = make_renderer(run.model).render_camera(run.params, run.aux, np.asarray(run.scene["train_poses"][0]), cam)
    out = Path(a.run_dir) / "exports"
    out.mkdir(exist_ok=True)
    save_png(out / "toy.png", np.asarray(rgb["rgb"]))
    rec = {"file": str(out / "toy.json"), "picture": "toy.png", "count": count * a.scale, "step": run.step}
    (out / "toy.json").write_text(json.dumps(rec))
    RunFolder(a.run_dir).write_record("toy", rec)
    return rec


EXPORTER = Exporter(
    name="toy", summary="the run's parameter count", args=ExportToyArgs, accepts=lambda supports: True,
    needs="parameters", outputs=("toy.json", "toy.png"), export=export_toy,
    wrote=lambda rec: f"wrote {rec['file']}: {rec['count']:g} parameters", facts="{count:g} parameters".format_map)
