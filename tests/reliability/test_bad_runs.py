"""Damaged run folders and broken inputs, through every verb that reads them: one line naming the file or
flag (and what to do), exit 1, no traceback, and nothing in the run folder or the inputs changed.

Damage classes (each a copy of one small trained run):
    truncated checkpoints   every checkpoint cut short (a single damaged one is skipped: test_safe_loading)
    no checkpoint           the checkpoints folder emptied
    broken config.json      not JSON; JSON that is not a nerfkit config
    broken scene.json       not JSON; missing
    missing images          the data folder the run was trained on has gone
Inputs: a baked folder that is not one (eval --baked, view --baked), a camera path that is not one
(render --camera-path), a COLMAP model of garbage (train); a disk that fills during render, eval, import,
bake and a textured export."""

from __future__ import annotations

import errno
import hashlib
import json
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from splat_files import gsplat_like_ply

import nerfkit.bake.bake as bake
import nerfkit.evaluation.evaluate as evaluate
import nerfkit.export.texture as texture
from nerfkit.cli.main import main
from nerfkit.data.procedural.scene import make_scene
from nerfkit.training import checkpoint as ckpt_lib

# A small fast-field run (every verb accepts it, bake included).
SMALL = ["--preset", "demo", "--hash-levels", "4", "--hash-log2-size", "12", "--hash-max-res", "64", "--occ-res", "16",
         "--march-steps", "64", "--max-samples", "4096", "--batch-rays", "256", "--no-progress", "--max-steps", "4",
         "--val-every", "4", "--ckpt-every", "2", "--log-every", "2"]

VERBS = {
    "eval": ["eval", "{run}", "--split", "test"],
    "render": ["render", "{run}", "--orbit", "2"],
    "export-mesh": ["export", "mesh", "{run}", "--method", "levelset", "--resolution", "16", "--threshold", "0.01",
                    "--no-progress"],
    "export-pointcloud": ["export", "pointcloud", "{run}", "--no-progress"],
    "export-cameras": ["export", "cameras", "{run}"],
    "bake": ["bake", "{run}", "--out", "{tmp}/baked", "--resolution", "32", "--finetune-minutes", "0.05"],
    "resume": ["train", "{data}", "--out", "{run}", "--resume", "--no-progress", "--max-steps", "6"],
    "view": ["view", "{run}", "--port", "0"],
}


def _truncate_checkpoints(run, data):
    for p in ckpt_lib.list_checkpoints(run / "checkpoints"):
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 3])
    return "ckpt_"


def _no_checkpoint(run, data):
    for p in (run / "checkpoints").iterdir():
        p.unlink()
    return "checkpoint"


def _config_not_json(run, data):
    (run / "config.json").write_text('{"data": {"train_split": ')
    return "config.json"


def _config_not_a_config(run, data):
    (run / "config.json").write_text(json.dumps({"field": 3}))
    return "config.json"


def _scene_not_json(run, data):
    (run / "scene.json").write_text("[[[")
    return "scene.json"


def _scene_missing(run, data):
    (run / "scene.json").unlink()
    return "scene.json"


def _images_gone(run, data):
    shutil.rmtree(data)
    return str(data)


DAMAGE = {f.__name__[1:]: f for f in (_truncate_checkpoints, _no_checkpoint, _config_not_json, _config_not_a_config,
                                      _scene_not_json, _scene_missing, _images_gone)}
# Verbs that can do their job without the damaged part (they may succeed; if they fail, it is in one line).
MAY_SUCCEED = {"truncate_checkpoints": {"export-cameras"}, "no_checkpoint": {"export-cameras", "resume"},
               "scene_missing": {"resume"}, "scene_not_json": {"resume"},
               "images_gone": {"view"}}  # the viewer shows the training cameras without their photos


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    root = tmp_path_factory.mktemp("badruns")
    data = make_scene(root / "scene", size=16, n_train=4, n_val=1, n_test=1)
    assert main(["train", str(data), "--out", str(root / "run"), *SMALL]) == 0
    return root / "run", data


def _snapshot(folder: Path) -> dict:
    if not folder.exists():
        return {}
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


def _serve(argv: list[str]) -> tuple[int, str]:
    """A server verb in its own process: (0, "") once it prints its address (then Ctrl-C), else its exit."""
    proc = subprocess.Popen([sys.executable, "-m", "nerfkit", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        for line in proc.stdout:
            if line.startswith(("viewer for", "serving the baked scene")):  # nerfkit's line, after viser's banner
                proc.send_signal(signal.SIGINT)
                proc.wait(timeout=60)
                return 0, ""
        return proc.wait(timeout=60), proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()


def _run(argv: list[str], capsys) -> tuple[int, str]:
    if argv[0] == "view":  # a server: in its own process, so a damaged run that got served cannot hang the suite
        return _serve(argv)
    capsys.readouterr()
    code = main(argv)
    return code, capsys.readouterr().err


def _copy(trained, where: Path) -> tuple[Path, Path]:
    """A copy of the trained run and its data in `where`, the run pointing at the copy."""
    run0, data0 = trained
    run, data = where / "run", where / "scene"
    shutil.copytree(run0, run)
    shutil.copytree(data0, data)
    scene = json.loads((run / "scene.json").read_text())
    (run / "scene.json").write_text(json.dumps(dict(scene, data_dir=str(data))))
    return run, data


def _damaged_copy(trained, where: Path, damage: str) -> tuple[Path, Path, str]:
    """_copy, damaged."""
    run, data = _copy(trained, where)
    return run, data, DAMAGE[damage](run, data)


@pytest.mark.parametrize("damage", DAMAGE)
def test_damaged_run_folders(trained, tmp_path, capsys, damage):
    failed = []
    for verb, template in VERBS.items():
        where = tmp_path / verb
        run, data, named = _damaged_copy(trained, where, damage)
        before_run, before_data = _snapshot(run), _snapshot(data)
        code, err = _run([a.format(run=run, data=data, tmp=where) for a in template], capsys)
        if code == 0:
            assert verb in MAY_SUCCEED.get(damage, ()), f"{verb} succeeded on a run with {damage}"
            continue
        line = err.strip().splitlines()
        assert code == 1, (verb, code, err[-2000:])
        assert len(line) == 1 and "Traceback" not in err, (verb, err[-2000:])
        assert named in line[0] or (damage == "images_gone" and "--data" in line[0]), (verb, line[0])
        assert _snapshot(run) == before_run and _snapshot(data) == before_data, f"{verb} changed the user's files"
        assert not (where / "baked").exists()
        failed.append(verb)
    assert len(failed) >= len(VERBS) - len(MAY_SUCCEED.get(damage, ()))


def test_a_baked_folder_that_is_not_one(trained, tmp_path, capsys):
    run, _ = trained
    fake = tmp_path / "baked"
    fake.mkdir()
    (fake / "baked.json").write_text("{not json")
    before = _snapshot(run)
    for argv in (["eval", str(run), "--baked", str(fake)], ["view", "--baked", str(fake), "--port", "0"],
                 ["eval", str(run), "--baked", str(tmp_path / "nothing")]):
        code, err = _run(argv, capsys)
        assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, (argv, err)
        assert "baked" in err
    assert _snapshot(run) == before
    code, err = _run(["view", "--baked", str(fake), "--port", "-1"], capsys)
    assert code == 1 and "--port must be in 0..65535" in err and len(err.strip().splitlines()) == 1


EYE = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 4, 0, 0, 0, 1]  # 4 units up the z axis


@pytest.mark.parametrize("text", ["", "{", json.dumps({"camera_path": [{"camera_to_world": [1, 2]}]}),
                                  json.dumps({"camera_path": [{"camera_to_world": EYE, "fov": 50}], "fps": 0}),
                                  json.dumps({"camera_path": [{"camera_to_world": EYE, "fov": 50}],
                                              "render_width": 100000, "render_height": 64})])
def test_a_camera_path_that_is_not_one(trained, tmp_path, capsys, text):
    run, _ = trained
    path = tmp_path / "path.json"
    path.write_text(text)
    before = _snapshot(run)
    code, err = _run(["render", str(run), "--camera-path", str(path)], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert str(path) in err
    assert _snapshot(run) == before


@pytest.mark.parametrize("content", [b"", b"\x01\x00\x00\x00\x00\x00\x00\x00", bytes(range(256)) * 3])
def test_a_colmap_model_of_garbage(tmp_path, capsys, content):
    model = tmp_path / "cap" / "sparse" / "0"
    model.mkdir(parents=True)
    for name in ("cameras.bin", "images.bin", "points3D.bin"):
        (model / name).write_bytes(content)
    code, err = _run(["train", str(tmp_path / "cap"), "--out", str(tmp_path / "run"), "--preset", "tiny"], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert str(model) in err and not (tmp_path / "run").exists()


@pytest.mark.parametrize("flags,named", [(["--fps", "0"], "--fps"), (["--fps", "1000"], "--fps"),
                                         (["--width", "100000"], "--width"), (["--height", "0"], "--height"),
                                         (["--width", "1"], "the videos' colour format needs 2"),
                                         (["--width", "8000", "--camera-path", "TALL"], "--width / --height")])
def test_render_flags_out_of_range(trained, tmp_path, capsys, flags, named):
    """The last case: a width within bounds whose height, following a camera path's 1:2 aspect, is not."""
    run, _ = trained
    before = _snapshot(run)
    tall = tmp_path / "tall.json"
    tall.write_text(json.dumps({"camera_path": [{"camera_to_world": EYE, "fov": 50}], "render_width": 32,
                                "render_height": 64}))
    flags = [str(tall) if f == "TALL" else f for f in flags]
    source = [] if "--camera-path" in flags else ["--orbit", "2"]
    code, err = _run(["render", str(run), *source, "--out", str(tmp_path / "r"), *flags], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert named in err and not (tmp_path / "r").exists() and _snapshot(run) == before


def test_report_of_a_config_cut_short(trained, tmp_path, capsys):
    run, data, named = _damaged_copy(trained, tmp_path, "config_not_json")
    before = _snapshot(run)
    code, err = _run(["report", str(run)], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert named in err and _snapshot(run) == before  # the training's own report.html is left as it was
    _damaged_copy(trained, tmp_path / "whole", "scene_missing")  # the same verb on a readable config writes its page
    (tmp_path / "whole" / "run" / "report.html").unlink()
    assert _run(["report", str(tmp_path / "whole" / "run")], capsys)[0] == 0
    assert (tmp_path / "whole" / "run" / "report.html").is_file()


def _no_space(path) -> OSError:
    """What writing `path` raises on a full disk."""
    return OSError(errno.ENOSPC, "No space left on device", str(path))


def test_a_disk_that_fills_during_render_leaves_nothing_half_written(trained, tmp_path, capsys, monkeypatch):
    """The frames are written, then the video fails as a full disk does: one line naming the disk's reason, exit 1;
    a new --out (or the run's renders/ folder) does not appear, and an earlier render replaced with --overwrite
    keeps its files. The same command with room on the disk writes them all."""
    run, _ = trained
    write_video = evaluate.write_video

    def full(path, *a, **k):
        raise _no_space(path)

    earlier = tmp_path / "earlier"
    assert _run(["render", str(run), "--orbit", "2", "--out", str(earlier)], capsys)[0] == 0
    before, run_before = _snapshot(earlier), _snapshot(run)
    assert "rgb_0001.png" in before and "rgb.mp4" in before
    monkeypatch.setattr(evaluate, "write_video", full)
    for out, extra in ((tmp_path / "new" / "r", []), (earlier, ["--overwrite"]), (None, [])):
        argv = ["render", str(run), "--orbit", "3", *extra] + (["--out", str(out)] if out else [])
        code, err = _run(argv, capsys)
        error = [line for line in err.strip().splitlines() if line.startswith("nerfkit render:")]  # not the bar
        assert code == 1 and "Traceback" not in err and len(error) == 1 and "No space left" in error[0], err
        assert f"({out or run / 'renders' / 'orbit3_16x16'}/rgb.mp4)" in error[0], error  # not the hidden folder
    assert not (tmp_path / "new").exists() and _snapshot(earlier) == before and _snapshot(run) == run_before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier"]
    monkeypatch.setattr(evaluate, "write_video", write_video)
    assert _run(["render", str(run), "--orbit", "3", "--overwrite", "--out", str(earlier)], capsys)[0] == 0
    after = _snapshot(earlier)
    assert "rgb_0002.png" in after and after["rgb_0001.png"] != before["rgb_0001.png"]  # a third of a turn, not half
    assert json.loads((earlier / "render.json").read_text())["frames"] == 3


def test_a_disk_that_fills_during_eval_leaves_the_earlier_evaluation(trained, tmp_path, capsys, monkeypatch):
    """eval --overwrite of a run evaluated before, the disk filling after the first picture: one line, exit 1, and
    the run folder as it was (the earlier eval_test/ and eval_test.json); a new evaluation leaves no folder."""
    run0, data0 = trained
    run = tmp_path / "run"
    shutil.copytree(run0, run)
    save_png, calls = evaluate.save_png, []

    def fills(path, img):
        calls.append(path)
        if len(calls) > 1:
            raise _no_space(path)
        save_png(path, img)

    monkeypatch.setattr(evaluate, "save_png", fills)
    before = _snapshot(run)
    code, err = _run(["eval", str(run), "--split", "test"], capsys)
    error = [line for line in err.strip().splitlines() if line.startswith("nerfkit eval:")]  # not the bar
    assert code == 1 and "Traceback" not in err and len(error) == 1 and "No space left" in error[0], err
    assert f"({run / 'eval_test'}/" in error[0] and _snapshot(run) == before  # no eval_test/ nor its hidden sibling
    monkeypatch.setattr(evaluate, "save_png", save_png)
    assert _run(["eval", str(run), "--split", "test"], capsys)[0] == 0
    before = _snapshot(run)
    assert "eval_test/view_000.png" in before and "eval_test.json" in before
    monkeypatch.setattr(evaluate, "save_png", fills)
    calls.clear()
    code, err = _run(["eval", str(run), "--split", "test", "--overwrite"], capsys)
    assert code == 1 and "No space left" in err and _snapshot(run) == before, err


def _splat_file(path: Path, n: int = 300) -> Path:
    """A small .ply of n random Gaussians (gsplat's layout, SH degree 1)."""
    rng = np.random.default_rng(0)
    gsplat_like_ply(path, {
        "means": 0.5 * rng.normal(size=(n, 3)), "sh_dc": rng.normal(size=(n, 1, 3)), "sh_rest": np.zeros((n, 3, 3)),
        "opacity": rng.normal(size=n), "log_scales": np.full((n, 3), -3.0), "quats": np.tile([1.0, 0, 0, 0], (n, 1))})
    return path


def test_a_disk_that_fills_during_import_leaves_no_half_made_run(tmp_path, capsys, monkeypatch):
    """import splat, its checkpoint (the last file written, after the capture of renders, config.json and
    scene.json) failing as on a full disk: one line naming --out, exit 1; a new --out does not appear and an
    earlier import replaced with --overwrite keeps every file. With room, the run's scene.json names its capture
    where it lies (not the hidden folder it was made in), and eval scores it."""
    _splat_file(tmp_path / "g.ply")
    earlier = tmp_path / "earlier"
    assert _run(["import", "splat", str(tmp_path / "g.ply"), "--out", str(earlier)], capsys)[0] == 0
    before = _snapshot(earlier)
    assert "capture/transforms.json" in before and "checkpoints" in before

    def full(ckpt_dir, *a, **k):
        raise _no_space(Path(ckpt_dir) / "ckpt_000000.npz")

    monkeypatch.setattr(ckpt_lib, "save_checkpoint", full)
    for out, extra in ((tmp_path / "new" / "run", []), (earlier, ["--overwrite"])):
        code, err = _run(["import", "splat", str(tmp_path / "g.ply"), "--out", str(out), *extra], capsys)
        assert code == 1 and err.count("\n") == 1 and "No space left" in err, err
        assert f"({out / 'checkpoints'}/ckpt_000000.npz)" in err, err  # not the hidden folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "g.ply"] and _snapshot(earlier) == before
    monkeypatch.undo()
    out = tmp_path / "new" / "run"
    assert _run(["import", "splat", str(tmp_path / "g.ply"), "--out", str(out)], capsys)[0] == 0
    assert json.loads((out / "scene.json").read_text())["data_dir"] == str((out / "capture").resolve())
    assert _run(["eval", str(out), "--split", "test"], capsys)[0] == 0
    assert json.loads((out / "eval_test.json").read_text())["psnr"] >= 55  # its own renders, to 8-bit rounding
    (out / "exports").mkdir()
    shutil.copy(tmp_path / "g.ply", out / "exports" / "g.ply")  # the input inside what --overwrite would remove
    code, err = _run(["import", "splat", str(out / "exports" / "g.ply"), "--out", str(out), "--overwrite"], capsys)
    assert code == 1 and "which --overwrite removes with the earlier run" in err, err
    assert (out / "exports" / "g.ply").is_file()


def test_a_disk_that_fills_during_bake_leaves_the_earlier_bake(trained, tmp_path, capsys, monkeypatch):
    """bake of a fast-field run (the viewer page, its last files, failing as on a full disk) and of a splat run
    (the page's script failing): one line, exit 1; a new --out does not appear and an earlier bake replaced with
    --overwrite keeps every file."""
    run, _ = trained
    splat_run = tmp_path / "splat"
    assert _run(["import", "splat", str(_splat_file(tmp_path / "g.ply")), "--out", str(splat_run)], capsys)[0] == 0
    field = ["--resolution", "32", "--finetune-minutes", "0"]
    for source, extra, target, attribute in ((run, field, bake, "write_web"), (splat_run, [], shutil, "copyfile")):
        earlier = tmp_path / "earlier"
        shutil.rmtree(earlier, ignore_errors=True)
        assert _run(["bake", str(source), "--out", str(earlier), *extra], capsys)[0] == 0
        before = _snapshot(earlier)
        with monkeypatch.context() as m:
            m.setattr(target, attribute, lambda *a, **k: (_ for _ in ()).throw(_no_space(a[-1])))
            for out, more in ((tmp_path / "new" / "baked", []), (earlier, ["--overwrite"])):
                code, err = _run(["bake", str(source), "--out", str(out), *extra, *more], capsys)
                error = [line for line in err.splitlines() if line.startswith("nerfkit bake:")]  # not the bar
                assert code == 1 and "Traceback" not in err and len(error) == 1 and "No space left" in error[0], err
                assert f"({out}" in error[0], error  # not the hidden folder
        assert not (tmp_path / "new").exists() and _snapshot(earlier) == before, source
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert _run(["bake", str(splat_run), "--out", str(earlier), "--overwrite"], capsys)[0] == 0
    assert _snapshot(earlier).keys() == before.keys()


def test_a_disk_that_fills_during_a_textured_export_leaves_none_of_its_files(trained, tmp_path, capsys, monkeypatch):
    """export mesh --texture to .obj writes three files (.png, .mtl, .obj); the .obj, the last, failing half written
    as on a full disk: one line naming it, exit 1; none of the three appears, nor the folder made for them, and an
    earlier export replaced with --overwrite keeps all three."""
    run0, _ = trained
    run = tmp_path / "run"
    shutil.copytree(run0, run)
    mesh = ["export", "mesh", str(run), "--method", "levelset", "--resolution", "16", "--threshold", "0.01",
            "--texture", "--texture-size", "64", "--no-progress", "--out"]
    earlier = tmp_path / "earlier" / "mesh.obj"
    assert _run([*mesh, str(earlier)], capsys)[0] == 0
    before = _snapshot(earlier.parent)
    assert sorted(before) == ["mesh.mtl", "mesh.obj", "mesh.png"]
    write_together = texture.write_together

    def fills(files):
        def half(tmp):
            Path(tmp).write_text("v 0 0 0\n")
            raise _no_space(tmp)
        write_together([*files[:-1], (files[-1][0], half)])

    monkeypatch.setattr(texture, "write_together", fills)
    for out, extra in ((tmp_path / "new" / "mesh.obj", []), (earlier, ["--overwrite"])):
        code, err = _run([*mesh, str(out), *extra], capsys)
        assert code == 1 and err.count("\n") == 1 and f"No space left on device ({out})" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "run"] and _snapshot(earlier.parent) == before


def test_a_disk_that_fills_during_training_says_how_to_go_on(trained, tmp_path, capsys, monkeypatch):
    """The second checkpoint (step 4) failing as on a full disk: one line with the disk's reason, the checkpoint the
    run keeps (step 2) and the command that resumes from it, exit 1; that command, with room, ends the run. The
    first checkpoint failing instead: the line says none was saved and how to start again."""
    _, data = trained
    run = tmp_path / "run"
    save, calls = ckpt_lib.save_checkpoint, []

    def fills(ckpt_dir, step, *a, **k):
        calls.append(step)
        if len(calls) == fail_at:
            raise _no_space(ckpt_lib.checkpoint_path(Path(ckpt_dir), step))
        return save(ckpt_dir, step, *a, **k)

    monkeypatch.setattr(ckpt_lib, "save_checkpoint", fills)
    for fail_at, says in ((1, "no checkpoint was saved: free space there, then nerfkit train"),
                          (2, "the run keeps its checkpoint of step 2: free space there, then nerfkit train")):
        calls.clear()
        code, err = _run(["train", str(data), "--out", str(run), *SMALL, "--overwrite"], capsys)
        error = [line for line in err.splitlines() if line.startswith("nerfkit train:")]
        assert code == 1 and "Traceback" not in err and len(error) == 1 and "No space left" in error[0], err
        assert says in error[0] and f"({run / 'checkpoints'}/ckpt_0000000{2 * fail_at}.msgpack)" in error[0], error
    assert error[0].endswith(f"--out {run} --resume")
    monkeypatch.undo()
    assert _run(["train", str(data), "--out", str(run), "--resume", "--no-progress"], capsys)[0] == 0
    assert [ckpt_lib.checkpoint_step(p) for p in ckpt_lib.list_checkpoints(run / "checkpoints")][-1] == 4


@pytest.mark.parametrize("argv, says", [
    (["export", "cameras", "{run}", "--out", "{run}/config.json", "--overwrite"],
     "config.json: is one of the run's own files, which the export reads; name another file"),
    (["export", "cameras", "{run}", "--out", "{data}/transforms_train.json", "--overwrite"],
     "transforms_train.json: is a file of the capture"),
    (["eval", "{run}", "--split", "test", "--downscale", "8"], "the photos are 2x2 px at this scale, too small to "
                                                               "score (at least 3x3); use a smaller --downscale"),
    (["bake", "{run}", "--out", "{tmp}/b", "--finetune-minutes", "nan"], "--finetune-minutes must be a number of "
                                                                         "minutes >= 0 (got nan)"),
    (["experiment", "pe-ablation", "{data}", "--out", "{run}", "--max-steps", "1"], "holds a run or a capture"),
    (["make-scene", "{tmp}/s", "--seed", "-1"], "--seed must be >= 0 (got -1)"),
    (["benchmark", "{tmp}", "--out", "{tmp}", "--max-steps", "1"], "is the folder of scenes itself"),
    (["train", "{data}", "--out", "{run}", "--resume", "--max-steps", "2"], "is already at step 4, so nothing would "
                                                                             "train; pass a --max-steps above 4"),
    (["export", "pointcloud", "{run}", "--voxel-size", "1e300"], "is larger than the scene's box"),
    (["export", "pointcloud", "{run}", "--voxel-size", "1e-300"], "pass --voxel-size 0 to keep every point"),
])
def test_outputs_that_are_inputs_and_values_out_of_range(trained, tmp_path, capsys, argv, says):
    """An output that would replace a file the command reads, or a value it cannot use: one line, exit 1, the run
    and its capture unchanged, nothing written."""
    run, data = _copy(trained, tmp_path)
    before = _snapshot(run), _snapshot(data)
    code, err = _run([a.format(run=run, data=data, tmp=tmp_path) for a in argv], capsys)
    error = [line for line in err.splitlines() if line.startswith("nerfkit ")]  # not the bar
    assert code == 1 and "Traceback" not in err and len(error) == 1 and says in error[0], err
    assert (_snapshot(run), _snapshot(data)) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run", "scene"]
