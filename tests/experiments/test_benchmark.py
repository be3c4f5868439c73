"""`nerfkit benchmark ROOT`: every scene trained and evaluated into one table; resumable (a finished
scene with the same settings is reused, an interrupted one resumed; other settings are refused or, with
--overwrite, trained again); a failed scene is a row marked failed and exit 1; --jobs runs scenes in
parallel processes; bad input is a one-line error."""

from __future__ import annotations

import json
import shutil

import imageio.v3 as iio
import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.core.errors import ConfigError, DataError
from nerfkit.core.presets import preset
from nerfkit.core.viz import read_jsonl
from nerfkit.data.procedural.scene import make_scene
from nerfkit.experiments.benchmark import (
    RESULT,
    SETTINGS,
    benchmark,
    find_scenes,
    nerfkit_version,
    scene_settings,
)
from nerfkit.training.trainer import Trainer


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    r = tmp_path_factory.mktemp("bench") / "scenes"
    make_scene(r / "alpha", size=16, n_train=4, n_val=2, n_test=1, seed=1)
    make_scene(r / "beta", size=16, n_train=4, n_val=2, n_test=1, seed=2)
    (r / "notes").mkdir()  # not a scene: ignored
    return r


def test_benchmark_trains_every_scene_resumes_the_interrupted_one_and_skips_finished_ones(root, tmp_path, capsys):
    out = tmp_path / "out"
    cfg = preset("tiny")
    cfg.train.max_steps = 2
    Trainer(root / "beta", out / "beta", cfg, progress=False).run()  # an interrupted scene: no benchmark.json
    (out / "beta" / SETTINGS).write_text(json.dumps(scene_settings(root / "beta", "tiny", None, 4, 1,
                                                                  nerfkit_version())))
    assert main(["benchmark", str(root), "--out", str(out), "--preset", "tiny", "--max-steps", "4",
                 "--no-progress"]) == 0
    table = json.loads((out / "results.json").read_text())
    rows = {r["scene"]: r for r in table["scenes"]}
    assert sorted(rows) == ["alpha", "beta"]
    assert rows["beta"]["resumed"] and not rows["alpha"]["resumed"]
    assert [r["step"] for r in read_jsonl(out / "beta" / "metrics.jsonl")][-1] == 4
    for r in rows.values():
        assert r["steps"] == 4 and r["split"] == "val" and r["n_views"] == 2
        ev = json.loads((out / r["scene"] / "eval_val.json").read_text())
        assert r["psnr"] == pytest.approx(ev["psnr"])
    assert table["mean"]["psnr"] == pytest.approx(np.mean([r["psnr"] for r in rows.values()]))
    md = (out / "results.md").read_text()
    assert "| alpha |" in md and "| beta |" in md and "**mean**" in md
    assert iio.imread(out / "results.png").shape[0] > 100
    stamps = {s: (out / s / RESULT).stat().st_mtime_ns for s in rows}
    capsys.readouterr()
    assert main(["benchmark", str(root), "--out", str(out), "--preset", "tiny", "--max-steps", "4",
                 "--no-progress"]) == 0
    assert "finished earlier with the same settings" in capsys.readouterr().out
    assert stamps == {s: (out / s / RESULT).stat().st_mtime_ns for s in rows}


def test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite(root, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["benchmark", str(root), "--out", str(out), "--preset", "tiny", "--no-progress", "--only", "alpha"]
    assert main([*args, "--max-steps", "2"]) == 0
    before = json.loads((out / "alpha" / RESULT).read_text())
    capsys.readouterr()
    assert main([*args, "--max-steps", "3"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_steps 2 -> 3" in err[0] and "--overwrite" in err[0]
    assert json.loads((out / "alpha" / RESULT).read_text()) == before  # nothing changed
    assert main([*args, "--max-steps", "3", "--overwrite"]) == 0
    after = json.loads((out / "alpha" / RESULT).read_text())
    assert after["steps"] == 3 and after["settings"]["max_steps"] == 3 and not after["resumed"]
    # A run folder with no record of its settings (trained by hand) is not taken for a result either.
    (out / "alpha" / SETTINGS).unlink()
    assert main([*args, "--max-steps", "3"]) == 1
    assert SETTINGS in capsys.readouterr().err


def test_a_failed_scene_is_a_row_and_a_nonzero_exit(root, tmp_path, capsys):
    bad_root = tmp_path / "scenes"
    shutil.copytree(root, bad_root)
    (bad_root / "beta" / "train" / "r_0.png").write_bytes(b"not a png")
    out = tmp_path / "out"
    assert main(["benchmark", str(bad_root), "--out", str(out), "--preset", "tiny", "--max-steps", "2",
                 "--no-progress"]) == 1
    table = json.loads((out / "results.json").read_text())
    rows = {r["scene"]: r for r in table["scenes"]}
    assert rows["alpha"]["status"] == "finished" and rows["beta"]["status"] == "failed"
    assert "r_0.png" in rows["beta"]["error"] and table["failed"] == ["beta"]
    assert table["mean"]["scenes"] == 1 and table["mean"]["psnr"] == pytest.approx(rows["alpha"]["psnr"])
    assert "mean of 1 of 2 scenes" in (out / "results.md").read_text()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1 of 2 scene(s) failed (beta)" in err[0]


def test_jobs_run_scenes_in_their_own_processes(root, tmp_path):
    out = tmp_path / "jobs"
    table = benchmark(root, out, preset="tiny", max_steps=2, jobs=2, progress=False, log=lambda *_: None)
    assert sorted(r["scene"] for r in table["scenes"]) == ["alpha", "beta"]
    for s in ("alpha", "beta"):
        assert (out / s / "benchmark.log").is_file() and (out / s / RESULT).is_file()


def test_bad_requests_are_one_line_errors(root, tmp_path, capsys):
    assert [p.name for p in find_scenes(root)] == ["alpha", "beta"]
    with pytest.raises(DataError, match="is one scene"):
        find_scenes(root / "alpha")
    with pytest.raises(DataError, match="no scene folders"):
        find_scenes(root / "notes")
    with pytest.raises(ConfigError, match="budget"):
        benchmark(root, tmp_path / "a", preset="tiny")
    with pytest.raises(DataError, match="--only gamma"):
        benchmark(root, tmp_path / "b", preset="tiny", max_steps=1, only="gamma")
    capsys.readouterr()
    assert main(["benchmark", str(root / "alpha"), "--out", str(tmp_path / "c"), "--max-steps", "1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is one scene" in err[0]
