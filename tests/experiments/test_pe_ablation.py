"""`nerfkit experiment pe-ablation` end to end on a tiny procedural scene with a tiny budget:
three run folders that differ only in the positional encoding, results table, the six
overlaid plots, image grids, orbit videos, and a report whose every link exists."""

from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest
from html_refs import refs

from nerfkit.cli.main import main
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.presets import PRESETS
from nerfkit.data.procedural.scene import make_scene
from nerfkit.experiments import PE_ABLATION, pe_ablation

STEPS = 10
RUNS = ("model1_pe", "model2_no_pe", "model3_pe_l5")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("exp") / "scene", size=16, n_train=6, n_val=4, n_test=1, seed=2)


@pytest.fixture(scope="module")
def exp(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("exp") / "pe"
    code = main(["experiment", "pe-ablation", str(scene), "--out", str(out), "--preset", "tiny",
                 "--max-steps", str(STEPS), "--val-every", "5", "--eval-every", "2", "--orbit-frames", "3",
                 "--no-progress"])
    assert code == 0
    return out


def test_runs_differ_only_in_the_encoding(exp):
    cfgs = [json.loads((exp / r / "config.json").read_text()) for r in RUNS]
    fields = [(c["field"]["pe"], c["field"]["l_xyz"], c["field"]["l_dir"]) for c in cfgs]
    assert fields[0] == (True, 10, 4) and fields[1][0] is False and fields[2] == (True, 5, 2)
    for c in cfgs:
        for k in ("pe", "l_xyz", "l_dir"):
            c["field"].pop(k)
    assert cfgs[0] == cfgs[1] == cfgs[2]  # same preset, seed and budget
    assert cfgs[0]["train"]["max_steps"] == STEPS


def test_results_table(exp):
    res = json.loads((exp / "results.json").read_text())
    assert [m["run_dir"] for m in res["models"]] == list(RUNS)
    assert [m["label"] for m in res["models"]] == [v.label for v in PE_ABLATION]
    for m in res["models"]:
        assert m["steps"] == STEPS
        assert np.isfinite(m["psnr"]) and 0 < m["psnr"] < 60
        assert np.isfinite(m["ssim"]) and -1 <= m["ssim"] <= 1
    assert res["eval"]["n_views"] == 2  # every 2nd of 4 val views
    md = (exp / "results.md").read_text()
    rows = [line for line in md.splitlines() if line.startswith("| Model-")]
    assert len(rows) == 3
    for m, row in zip(res["models"], rows):
        assert f"{m['psnr']:.2f}" in row and f"{m['ssim']:.4f}" in row


def test_plots_grids_videos_and_depth_arrays(exp):
    for metric in ("loss", "train_psnr", "val_psnr"):
        for axis in ("step", "time"):
            assert iio.imread(exp / "plots" / f"{metric}_vs_{axis}.png").ndim == 3
    grids = sorted(exp.glob("grid_view_*.png"))
    assert len(grids) >= 2
    assert iio.imread(grids[0]).shape[1] > 4 * 16  # GT + three models side by side
    for r in RUNS:
        video = exp / r / "renders" / "orbit3_16x16" / "rgb.mp4"
        assert video.read_bytes()[4:8] == b"ftyp"
        depth = np.load(exp / r / "eval_val" / "view_000_depth.npy")
        assert depth.shape == (16, 16) and depth.dtype == np.float32
        assert (exp / r / "report.html").is_file()


def test_report_links_everything(exp):
    page = exp / "report.html"
    text = page.read_text()
    for v in PE_ABLATION:
        assert v.label in text and v.description in text
    found = refs(page)
    missing = [str(p) for _, p in found if not p.exists()]
    assert not missing, missing
    srcs = {p for tag, p in found if tag in ("img", "video")}
    expected = {(exp / "plots" / f"{m}_vs_{a}.png").resolve() for m in ("loss", "train_psnr", "val_psnr")
                for a in ("step", "time")}
    expected |= {g.resolve() for g in exp.glob("grid_view_*.png")}
    expected |= {(exp / r / "renders" / "orbit3_16x16" / "rgb.mp4").resolve() for r in RUNS}
    assert expected <= srcs, expected - srcs
    assert "w<sub>i</sub> t<sub>i</sub>" in text  # states how depth is computed
    for r in RUNS:  # each model's own report: links exist too
        assert all(p.exists() for _, p in refs(exp / r / "report.html"))


def test_report_command_rewrites_reports(exp, capsys):
    (exp / "report.html").unlink()
    assert main(["report", str(exp)]) == 0
    assert (exp / "report.html").is_file()
    assert main(["report", str(exp / RUNS[1])]) == 0
    assert "report.html" in capsys.readouterr().out
    assert main(["report", str(exp / "plots")]) == 1  # not a run folder: a clean error


def test_bad_requests_fail_before_training(scene, exp, tmp_path):
    with pytest.raises(ConfigError, match="budget"):
        pe_ablation(scene, tmp_path / "a", preset="tiny")
    if "ngp" in PRESETS:  # a preset whose field has no positional encoding to ablate
        with pytest.raises(ConfigError, match="MLP preset"):
            pe_ablation(scene, tmp_path / "b", preset="ngp", max_steps=2)
    with pytest.raises(NerfkitError, match="already holds"):
        pe_ablation(scene, exp, preset="tiny", max_steps=2)
