"""Adding a method and a capture format: one definition each (tests/toys.py) plus one registry line,
with no edit to the trainer, renderers, CLI or run-folder code. The toy method trains on the toy format
through `nerfkit train`, evaluates through `nerfkit eval`, and reloads through RunFolder."""

import json
import math
import shutil

import jax

import numpy as np
import pytest
from imageio.v3 import imread, imwrite
from toys import ConstantColour, ToyFormat

from nerfkit.cli.main import main
from nerfkit.core.metrics import psnr
from nerfkit.data.formats import registry
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models import registry as methods
from nerfkit.run.folder import RunFolder


@pytest.fixture
def toy_capture(tmp_path):
    """The procedural scene's train views rewritten as a toy.json capture (RGB on white, no alpha)."""
    blender = make_scene(tmp_path / "blender", size=24, n_train=12, n_val=2, n_test=2)
    meta = json.loads((blender / "transforms_train.json").read_text())
    root = tmp_path / "toy"
    root.mkdir()
    frames = []
    for k, f in enumerate(meta["frames"]):
        rgba = imread(blender / (f["file_path"] + ".png")).astype(np.float64) / 255
        rgb = rgba[..., :3] * rgba[..., 3:] + (1 - rgba[..., 3:])
        name = f"view_{k:02d}.png"
        imwrite(root / name, np.round(rgb * 255).astype(np.uint8))
        frames.append({"file": name, "c2w": f["transform_matrix"]})
    focal = 0.5 * 24 / math.tan(0.5 * meta["camera_angle_x"])
    (root / "toy.json").write_text(json.dumps({"focal": focal, "frames": frames}))
    return root


def test_a_toy_method_trains_on_a_toy_format_through_the_cli(toy_capture, tmp_path, monkeypatch):
    monkeypatch.setattr(registry, "FORMATS", [ToyFormat, *registry.FORMATS])  # the format's registry line
    monkeypatch.setitem(methods.METHODS, "toy", ConstantColour)  # the method's registry line
    from nerfkit.core import presets

    def toy_preset():
        cfg = presets.preset("tiny")
        cfg.field.kind = "toy"
        return cfg

    monkeypatch.setitem(presets.PRESETS, "toy", toy_preset)  # how a user picks it: --preset toy
    run = tmp_path / "run"
    assert main(["train", str(toy_capture), "--out", str(run), "--preset", "toy", "--max-steps", "300",
                 "--lr", "0.05", "--no-progress"]) == 0
    assert "toy: one colour for every ray" in (run / "report.html").read_text()  # the method names itself
    trained = RunFolder(run).load()
    assert trained.scene["format"] == "toy"
    colour = 1 / (1 + np.exp(-np.asarray(trained.params["logit"])))
    # The MSE minimiser is the mean training pixel; Adam's last steps (lr 0.05 on the logit, batches of
    # 1024 pixels: batch-mean noise ~ 0.3 / 32) leave it within 0.02 of it.
    held = [p for k, p in enumerate(sorted(toy_capture.glob("view_*.png"))) if k % 4 == 0]
    train = [p for p in sorted(toy_capture.glob("view_*.png")) if p not in held]
    pixels = np.concatenate([imread(p).reshape(-1, 3) / 255 for p in train])
    np.testing.assert_allclose(colour, pixels.mean(0), atol=0.02)
    # nerfkit eval on the held-out views: the PSNR of that one colour against them.
    assert main(["eval", str(run), "--split", "test"]) == 0
    ev = json.loads((run / "eval_test.json").read_text())
    expected = np.mean([psnr(np.broadcast_to(colour, (24, 24, 3)), imread(p) / 255) for p in held])
    assert ev["n_views"] == len(held) == 3
    assert abs(ev["psnr"] - expected) < 0.05


def test_a_toy_exporter_runs_through_the_cli_and_the_report(procedural_run, tmp_path, capsys, monkeypatch):
    """tests/toy_exporter.py plus one registry line: `nerfkit export toy RUN` parses its own flags, writes its
    files and record, and the run report shows it; `nerfkit export --help` lists it."""
    from nerfkit.export import registry as exporters

    monkeypatch.setitem(exporters.EXPORTERS, "toy", "toy_exporter")  # the exporter's registry line
    run = tmp_path / "run"
    shutil.copytree(procedural_run[0], run)
    assert main(["export", "toy", str(run), "--scale", "2"]) == 0
    rec = json.loads((run / "exports" / "export_toy.json").read_text())
    trained = RunFolder(run).load()
    count = sum(int(np.size(p)) for p in jax.tree_util.tree_leaves(trained.params))
    assert rec["count"] == 2 * count > 0
    assert f"wrote {run / 'exports' / 'toy.json'}: {2 * count:g} parameters" in capsys.readouterr().out
    assert imread(run / "exports" / "toy.png").std() > 0  # a render, not a blank image
    from nerfkit.report.run import write_report

    assert f"{2 * count:g} parameters" in write_report(run).read_text()
    assert main(["export", "--help"]) == 0
    assert "toy" in capsys.readouterr().out


def test_a_toy_rasteriser_backend_trains_splats_through_the_cli(tmp_path, monkeypatch):
    """tests/toy_backend.py plus one registry line: `nerfkit train --preset splat --backend toy` trains and
    evaluates through it (the toy records each trace), and an unknown backend is one clear error."""
    import toy_backend

    from nerfkit.models.splat import backends

    monkeypatch.setitem(backends.BACKENDS, "toy", "toy_backend")  # the backend's registry line
    scene = make_scene(tmp_path / "scene", size=24, n_train=6, n_val=2, n_test=2)
    run = tmp_path / "run"
    assert main(["train", str(scene), "--out", str(run), "--preset", "splat", "--backend", "toy", "--max-steps", "20",
                 "--capacity", "2000", "--val-every", "20", "--no-progress"]) == 0
    assert (24, 24) in toy_backend.TRACED
    assert json.loads((run / "config.json").read_text())["splat"]["backend"] == "toy"
    assert main(["eval", str(run), "--split", "test", "--downscale", "2"]) == 0  # a new size: traced again
    assert (12, 12) in toy_backend.TRACED
    assert json.loads((run / "eval_test.json").read_text())["psnr"] > 10
    assert main(["train", str(scene), "--out", str(tmp_path / "bad"), "--preset", "splat", "--backend", "nope",
                 "--max-steps", "2", "--no-progress"]) == 1
    assert not (tmp_path / "bad").exists()
