"""CLI smoke tests: every verb runs, writes what it promises, and fails cleanly on bad input."""

from __future__ import annotations

import errno
import json
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.core.metrics import psnr
from nerfkit.data.procedural.scene import make_scene
from nerfkit.training import checkpoint as ckpt_lib

TRAIN = ["--preset", "tiny", "--no-progress", "--max-steps", "8", "--val-every", "4", "--ckpt-every", "4",
         "--log-every", "2"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("cli") / "scene", size=16, n_train=6, n_val=2, n_test=3)


@pytest.fixture(scope="module")
def run(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "run"
    assert main(["train", str(scene), "--out", str(out), *TRAIN]) == 0
    return out


def test_help_lists_commands(capsys):
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    for verb in ("demo", "make-scene", "train", "eval", "render"):
        assert verb in text


def test_console_script_entry_point():
    for preset, flags in (("ngp", ("--hash-levels", "--march-steps", "--occ-res")),
                          ("seed", ("--no-pe", "--n-importance", "--depth", "--width"))):
        out = subprocess.run([sys.executable, "-m", "nerfkit", "train", "--preset", preset, "--help"],
                             capture_output=True, text=True)
        assert out.returncode == 0
        for flag in ("--out", "--preset", "--max-steps", "--max-minutes", "--downscale", "--seed", "--resume",
                     "--train-split", "--val-split", *flags):
            assert flag in out.stdout, (preset, flag)


def test_unknown_command_fails_in_one_line(capsys):
    assert main(["fly"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown command 'fly'" in err[0] and "nerfkit --help" in err[0]


def test_what_the_machine_refuses_is_one_line_naming_the_path(tmp_path, capsys):
    """--out under a file (the OS says no) and a size no memory holds: one line each, exit 1, no traceback."""
    (tmp_path / "a_file").write_text("mine")
    assert main(["make-scene", str(tmp_path / "s"), "--size", "8", "--n-train", "2", "--n-val", "1",
                 "--n-test", "0"]) == 0
    capsys.readouterr()
    out = tmp_path / "a_file" / "run"
    assert main(["train", str(tmp_path / "s"), "--out", str(out), "--preset", "tiny", "--max-steps", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "--out" in err[0], err
    assert (tmp_path / "a_file").read_text() == "mine"
    assert main(["make-scene", str(tmp_path / "big"), "--size", "5000"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--size" in err[0] and not (tmp_path / "big").exists(), err


def test_train_writes_run_folder(run):
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["train"]["max_steps"] == 8 and cfg["field"]["width"] == 32
    assert [r["step"] for r in map(json.loads, (run / "metrics.jsonl").read_text().splitlines())] == [2, 4, 6, 8]
    assert [p.name for p in ckpt_lib.list_checkpoints(run / "checkpoints")] == ["ckpt_00000004.msgpack",
                                                                               "ckpt_00000008.msgpack"]
    assert (run / "plots" / "val_psnr.png").is_file()


def test_train_refuses_to_overwrite_a_run(scene, run, capsys):
    assert main(["train", str(scene), "--out", str(run), *TRAIN]) == 1
    assert "--resume" in capsys.readouterr().err


def test_resume_continues_to_total_steps(scene, tmp_path):
    out = tmp_path / "run"
    assert main(["train", str(scene), "--out", str(out), *TRAIN]) == 0
    assert main(["train", str(scene), "--out", str(out), "--resume", "--max-steps", "12", "--no-progress"]) == 0
    steps = [r["step"] for r in map(json.loads, (out / "metrics.jsonl").read_text().splitlines())]
    assert steps == [2, 4, 6, 8, 10, 12]
    assert ckpt_lib.latest_checkpoint(out / "checkpoints").name == "ckpt_00000012.msgpack"


def test_eval_writes_json(scene, run, capsys):
    assert main(["eval", str(run), "--data", str(scene), "--split", "test", "--every", "2"]) == 0
    res = json.loads((run / "eval_test.json").read_text())
    assert {"psnr", "ssim", "per_view"} <= set(res)
    assert [v["view"] for v in res["per_view"]] == [0, 2]
    assert np.isclose(res["psnr"], np.mean([v["psnr"] for v in res["per_view"]]))
    assert "mean" in capsys.readouterr().out


def test_eval_fit_poses_is_refused_where_the_model_cannot_fit_a_pose(scene, run, capsys):
    """--fit-poses on a radiance field's run: one line naming the flag, nothing written (splat runs fit poses:
    tests/models/splat/test_pose_fit.py)."""
    before = sorted(p.name for p in run.iterdir())
    assert main(["eval", str(run), "--data", str(scene), "--split", "test", "--fit-poses", "5"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--fit-poses" in err and "Gaussian splat runs can" in err
    assert sorted(p.name for p in run.iterdir()) == before


def test_eval_fit_colour_scores_the_right_halves_of_any_run(scene, run, capsys):
    """--fit-colour on a radiance field's run (the colour map is fitted on the render, whatever drew it): its own
    file beside the plain evaluation, each view's transform and its right half's score before the map; photos too
    narrow to split in two SSIM windows: one line naming --downscale, nothing written."""
    assert main(["eval", str(run), "--data", str(scene), "--split", "test", "--fit-colour"]) == 0
    res = json.loads((run / "eval_test_colour.json").read_text())
    assert "left half" in res["fitted_colour"] and "before the colour map" in capsys.readouterr().out
    half = slice(8, None)  # the scene's photos are 16 px wide
    for v in res["per_view"]:
        assert np.asarray(v["colour_fit"]["transform"]).shape == (3, 4)
        saved = iio.imread(run / "eval_test_colour" / f"view_{v['view']:03d}_rgb.png")[:, half] / 255.0  # as scored
        rgba = iio.imread(scene / v["name"])[:, half] / 255.0
        photo = rgba[..., :3] * rgba[..., 3:] + 1.0 - rgba[..., 3:]  # on the run's white background
        assert psnr(saved, photo) == pytest.approx(v["psnr"], abs=0.3)
        assert abs(v["psnr"] - v["colour_fit"]["psnr_unfitted"]) > 0.01  # the map was applied
    before = sorted(p.name for p in run.iterdir())
    assert main(["eval", str(run), "--data", str(scene), "--split", "test", "--fit-colour", "--downscale", "4",
                 "--overwrite"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--downscale" in err and "6x3" in err
    assert sorted(p.name for p in run.iterdir()) == before


def test_render_split_at_other_resolution(scene, run, tmp_path):
    out = tmp_path / "r"
    assert main(["render", str(run), "--data", str(scene), "--split", "test", "--width", "40", "--out", str(out)]) == 0
    assert iio.imread(out / "rgb_0000.png").shape == (40, 40, 3)
    assert np.load(out / "depth_0002.npy").shape == (40, 40)
    for video in ("rgb.mp4", "depth.mp4"):
        frames = iio.imread(out / video)
        assert frames.shape[0] == 3 and frames.shape[1:3] == (40, 40)


def test_render_orbit(scene, run, monkeypatch, capsys):
    assert main(["render", str(run), "--data", str(scene), "--orbit", "4"]) == 0
    assert len(list((run / "renders" / "orbit4_16x16").glob("rgb_*.png"))) == 4
    # Orbits are capped at ORBIT_MAX_WIDTH unless a size is given (as if the cap were below 16 px).
    import nerfkit.evaluation.evaluate

    monkeypatch.setattr(nerfkit.evaluation.evaluate, "ORBIT_MAX_WIDTH", 8)
    capsys.readouterr()
    assert main(["render", str(run), "--data", str(scene), "--orbit", "2"]) == 0
    assert "--width 16 renders the training size" in capsys.readouterr().out
    assert iio.imread(run / "renders" / "orbit2_8x8" / "rgb_0000.png").shape == (8, 8, 3)
    assert main(["render", str(run), "--data", str(scene), "--orbit", "2", "--width", "16"]) == 0
    assert "training size" not in capsys.readouterr().out and (run / "renders" / "orbit2_16x16").is_dir()


def test_render_camera_path(run, tmp_path, capsys):
    from nerfkit.rays.camera_path import write_camera_path
    from nerfkit.rays.cameras import look_at

    keys = [look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 1.0]), np.zeros(3)) for a in (0.0, 1.0, 2.0)]
    path = write_camera_path(tmp_path / "camera_path.json", keys, [40.0] * 3, 24, 18, seconds=0.5, fps=10)
    out = tmp_path / "p"
    assert main(["render", str(run), "--camera-path", str(path), "--out", str(out)]) == 0  # data: the run's own
    assert len(list(out.glob("rgb_*.png"))) == 5 and iio.imread(out / "rgb_0004.png").shape == (18, 24, 3)
    info = json.loads((out / "render.json").read_text())
    np.testing.assert_allclose(info["camera_to_world"][0], keys[0], atol=1e-5)  # Blender scene: identity transform
    capsys.readouterr()
    assert main(["render", str(run), "--camera-path", str(tmp_path / "none.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "none.json: no such camera path file" in err


def test_render_needs_split_or_orbit(scene, run, capsys):
    assert main(["render", str(run), "--data", str(scene)]) == 1
    assert "--split" in capsys.readouterr().err


def test_bad_data_dir_is_a_one_line_error(tmp_path, capsys):
    assert main(["train", str(tmp_path / "nope"), "--out", str(tmp_path / "run"), "--preset", "tiny"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "nope" in err and "does not exist" in err


def test_bad_config_value_is_reported(scene, tmp_path, capsys):
    assert main(["train", str(scene), "--out", str(tmp_path / "run"), "--preset", "tiny", "--near", "7"]) == 1
    assert "--near must be smaller than --far" in capsys.readouterr().err


def test_make_scene(tmp_path, capsys):
    args = ["make-scene", str(tmp_path / "s"), "--size", "8", "--n-train", "2", "--n-val", "1", "--n-test", "3"]
    assert main(args) == 0
    meta = {s: json.loads((tmp_path / "s" / f"transforms_{s}.json").read_text()) for s in ("train", "val", "test")}
    assert [len(m["frames"]) for m in meta.values()] == [2, 1, 3]
    assert iio.imread(tmp_path / "s" / "train" / "r_0.png").shape[:2] == (8, 8)
    # Into a folder that is not empty: refused, nothing changed; --overwrite writes (here other poses: --seed).
    capsys.readouterr()
    assert main(args) == 1 and "--overwrite" in capsys.readouterr().err
    assert main([*args, "--seed", "5", "--overwrite"]) == 0
    again = json.loads((tmp_path / "s" / "transforms_train.json").read_text())
    assert again["frames"][0]["transform_matrix"] != meta["train"]["frames"][0]["transform_matrix"]


def test_make_scene_on_a_disk_that_fills_leaves_nothing_half_written(tmp_path, capsys, monkeypatch):
    """The third depth map failing as on a full disk: one line naming it, exit 1; a new folder does not appear and
    one replaced with --overwrite keeps every earlier file."""
    from nerfkit.data.procedural import scene

    args = ["make-scene", str(tmp_path / "s"), "--size", "8", "--n-train", "2", "--n-val", "1", "--n-test", "3"]
    assert main([*args, "--seed", "1"]) == 0
    before = {p: p.read_bytes() for p in sorted((tmp_path / "s").rglob("*")) if p.is_file()}
    save, calls = scene.np.save, []

    def fills(path, array):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        save(path, array)

    monkeypatch.setattr(scene.np, "save", fills)
    for out, extra in ((tmp_path / "new", []), (tmp_path / "s", ["--overwrite"])):
        calls.clear()
        capsys.readouterr()
        assert main([*args[:1], str(out), *args[2:], *extra]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"No space left on device ({out / 'val' / 'r_0_depth.npy'})" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]
    assert {p: p.read_bytes() for p in sorted((tmp_path / "s").rglob("*")) if p.is_file()} == before


def test_view_bad_input_is_a_one_line_error(tmp_path, run, capsys):
    assert main(["view", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "nope" in err
    assert main(["view", str(run), "--port", "70000"]) == 1
    assert "--port must be in 0..65535" in capsys.readouterr().err


def test_view_serves_on_loopback_and_stops_on_ctrl_c(run):
    """`nerfkit view` prints its loopback address, answers HTTP there, and exits 0 on SIGINT."""
    import os
    import re
    import signal
    import time
    import urllib.request

    proc = subprocess.Popen([sys.executable, "-m", "nerfkit", "view", str(run), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    try:
        url, lines, end = None, [], time.monotonic() + 120
        while url is None and time.monotonic() < end:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            m = re.search(r"at (http://127\.0\.0\.1:\d+)", line)
            url = m.group(1) if m else None
        assert url, "".join(lines)
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
        proc.send_signal(signal.SIGINT)
        try:
            out, _ = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # say where it hangs: faulthandler prints every thread's stack on SIGABRT
            proc.send_signal(signal.SIGABRT)
            raise AssertionError("`nerfkit view` did not stop within 60 s of SIGINT:\n"
                                 + "".join(lines) + proc.communicate(timeout=30)[0]) from None
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, out
    assert "viewer stopped" in out and "Traceback" not in out
