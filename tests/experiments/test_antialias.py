"""`nerfkit experiment antialias` end to end on a tiny multiscale procedural scene with a 3-step budget:
run folders, PSNR per scale, per-scale grids and crops, the verdict, a report whose every link exists,
and one-line errors for data that is not multiscale and for flags that do not apply."""

from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest
from html_refs import refs

from nerfkit.cli.main import main
from nerfkit.core import presets
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.data.formats.multiscale import make_multiscale
from nerfkit.data.procedural.scene import make_scene
from nerfkit.experiments import antialias_experiment
from nerfkit.experiments.antialias import crop, detail_window

MODELS = ("nerf", "mipnerf")


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    root = tmp_path_factory.mktemp("aa")
    src = make_scene(root / "scene", size=16, n_train=4, n_val=2, n_test=1, seed=3)
    make_multiscale(src, root / "ms", 2, progress=False)
    return src, root / "ms"


def _chunk_of_the_images(make):
    """A preset whose renderer chunk is one 16 px image (256 rays): its own 4096 pads every image of this tiny
    scene to 16 times its rays, which made up most of this experiment's time (what is computed is the same)."""

    def small_chunk():
        cfg = make()
        cfg.train.chunk = 16 * 16
        return cfg

    return small_chunk


@pytest.fixture(scope="module")
def exp(scenes, tmp_path_factory):
    out = tmp_path_factory.mktemp("aa") / "exp"
    with pytest.MonkeyPatch.context() as mp:
        for name in MODELS:
            mp.setitem(presets.PRESETS, name, _chunk_of_the_images(presets.PRESETS[name]))
        code = main(["experiment", "antialias", str(scenes[1]), "--out", str(out), "--max-steps", "3",
                     "--budget-minutes", "5", "--models", ",".join(MODELS), "--eval-every", "1", "--no-progress"])
    assert code == 0
    return out


def test_every_model_is_scored_at_every_scale(exp):
    res = json.loads((exp / "results.json").read_text())
    assert [m["run_dir"] for m in res["models"]] == list(MODELS)
    for m in res["models"]:
        assert m["steps"] == 3
        assert [s["width"] for s in m["scales"]] == [16, 8]
        assert m["psnr"] == pytest.approx(np.mean([s["psnr"] for s in m["scales"]]))
        cfg = json.loads((exp / m["run_dir"] / "config.json").read_text())
        assert (cfg["field"]["depth"], cfg["field"]["width"]) == (4, 128)  # both MLPs at the small size
        assert cfg["field"]["kind"] == ("mip" if m["run_dir"] == "mipnerf" else "mlp")
        assert cfg["train"]["chunk"] == 256  # the presets of this test (_chunk_of_the_images)
    assert res["budget"]["max_steps"] == 3 and "mip-NeRF" in res["verdicts"][0]
    md = (exp / "results.md").read_text()
    assert "| 16 px | 8 px |" in md and res["verdicts"][0] in md


def test_grids_show_every_scale_and_the_report_links_everything(exp):
    res = json.loads((exp / "results.json").read_text())
    g = res["grids"][0]
    for key in ("scales", "crops"):
        img = iio.imread(exp / g[key])
        assert img.shape[0] > 2 * 100 and img.shape[1] > 3 * 100  # 2 scales x (ground truth + 2 models)
    text = (exp / "report.html").read_text()
    assert "mip-NeRF" in text and "16 px" in text and res["verdicts"][0] in text
    found = refs(exp / "report.html")
    assert not [p for _, p in found if not p.exists()]
    assert {(exp / g["scales"]).resolve(), (exp / g["crops"]).resolve()} <= {p for t, p in found if t == "img"}
    (exp / "report.html").unlink()
    assert main(["report", str(exp)]) == 0 and "mip-NeRF" in (exp / "report.html").read_text()


def test_detail_window_finds_the_textured_corner():
    img = np.ones((40, 40, 3))
    img[24:36, 4:16] = np.random.default_rng(0).uniform(0, 1, (12, 12, 3))
    top, left, side = detail_window(img)
    assert side == 0.25 and 20 <= top * 40 <= 26 and 0 <= left * 40 <= 8
    assert crop(img, (top, left, side)).shape == (10, 10, 3)
    assert crop(img[::4, ::4], (top, left, side)).shape[:2] == (2, 2)  # the same region at 1/4


def test_bad_requests_are_one_line_errors(scenes, exp, tmp_path, capsys):
    src, ms = scenes
    with pytest.raises(NerfkitError, match="not multiscale data.*make-multiscale"):
        antialias_experiment(src, tmp_path / "a", max_steps=2)
    with pytest.raises(ConfigError, match="budget"):
        antialias_experiment(ms, tmp_path / "b")
    with pytest.raises(ConfigError, match="unknown model"):
        antialias_experiment(ms, tmp_path / "c", max_steps=2, models=["nerf", "zipnerf"])
    with pytest.raises(NerfkitError, match="already holds"):
        antialias_experiment(ms, exp, max_steps=2, models=["nerf"])
    capsys.readouterr()
    assert main(["experiment", "antialias", str(ms), "--out", str(tmp_path / "d"), "--max-steps", "2",
                 "--preset", "ngp"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--preset does not apply" in err[0]
