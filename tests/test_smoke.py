"""Smoke test: every module imports and every main verb runs once, small, through the CLI.

CI runs these (`pytest -m smoke`) in a second venv installed with the lowest allowed direct
versions (`uv pip install --resolution lowest-direct`, see .ci/run), so a lower bound in
pyproject.toml that is not true fails here. They are part of the default suite too.
"""

from __future__ import annotations

import functools
import importlib
import json
import pkgutil

import imageio.v3 as iio
import numpy as np
import photos
import pytest

import nerfkit
from nerfkit.cli.main import main
from nerfkit.process.sfm import SfmOptions

pytestmark = pytest.mark.smoke

TRAIN = ["--preset", "tiny", "--no-progress", "--max-steps", "20", "--val-every", "10", "--ckpt-every", "10",
         "--log-every", "5"]


# Packages of optional extras (pyproject.toml) that a module may need; a module may fail to import
# for want of these only (none at present: the [warp] extra serves benchmarks/splat_alt_warp.py, outside src).
OPTIONAL: set[str] = set()


def test_every_module_imports():
    names = [m.name for m in pkgutil.walk_packages(nerfkit.__path__, "nerfkit.") if m.name != "nerfkit.__main__"]
    assert len(names) > 40
    for name in names:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name not in OPTIONAL:
                raise


def test_splat_rasteriser_numba_matches_the_reference():
    # Not a CLI verb yet; its numba kernels and jax.pure_callback(vmap_method=...) set bounds.
    import jax

    from nerfkit.models.splat.rasterize import rasterize

    rng = np.random.default_rng(0)
    n, w, h = 6, 24, 20
    fixed = dict(conics=np.tile(np.float32([0.1, 0.0, 0.1]), (n, 1)), opacities=np.full(n, 0.8, np.float32),
                 depths=rng.uniform(1, 2, n).astype(np.float32), radii=np.full(n, 8, np.int32),
                 background=np.zeros(3, np.float32), width=w, height=h)
    means = rng.uniform(0, [w, h], (n, 2)).astype(np.float32)
    colors = rng.uniform(0, 1, (n, 3)).astype(np.float32)

    def loss(m, c, backend):
        return rasterize(m, colors=c, backend=backend, **fixed)[0].sum()

    numba = jax.jit(jax.grad(loss, argnums=(0, 1)), static_argnums=2)(means, colors, "numba")
    reference = jax.grad(loss, argnums=(0, 1))(means, colors, "reference")
    for a, b in zip(numba, reference):
        np.testing.assert_allclose(a, b, atol=1e-4)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("smoke") / "scene"
    assert main(["make-scene", str(path), "--size", "32", "--n-train", "8", "--n-val", "1", "--n-test", "2"]) == 0
    return path


@pytest.fixture(scope="module")
def run(scene):
    out = scene.parent / "run"
    assert main(["train", str(scene), "--out", str(out), *TRAIN]) == 0
    return out


def test_train(run):
    assert [r["step"] for r in map(json.loads, (run / "metrics.jsonl").read_text().splitlines())] == [5, 10, 15, 20]
    assert (run / "checkpoints" / "ckpt_00000020.msgpack").is_file()


def test_eval(run):
    assert main(["eval", str(run), "--split", "test"]) == 0
    assert np.isfinite(json.loads((run / "eval_test.json").read_text())["psnr"])


def test_render_orbit(run, tmp_path):
    assert main(["render", str(run), "--orbit", "2", "--out", str(tmp_path / "orbit")]) == 0
    assert len(list(tmp_path.glob("orbit/**/*.png"))) >= 2 and list(tmp_path.glob("orbit/**/*.mp4"))


def test_exports_and_report(run, tmp_path):
    # A low threshold so the 20-step field has a surface; --max-faces runs the simplification.
    assert main(["export", "mesh", str(run), "--out", str(tmp_path / "mesh.ply"), "--resolution", "32",
                 "--method", "levelset", "--threshold", "0.01", "--max-faces", "50", "--no-carve", "--no-progress"]) == 0
    assert main(["export", "pointcloud", str(run), "--out", str(tmp_path / "points.ply"), "--min-opacity", "0.01",
                 "--no-progress"]) == 0
    assert main(["export", "cameras", str(run), "--out", str(tmp_path / "cameras.json")]) == 0
    for name in ("mesh.ply", "points.ply", "cameras.json"):
        assert (tmp_path / name).stat().st_size > 0, name
    mesh = json.loads((run / "exports" / "export_mesh.json").read_text())
    assert mesh["faces"] < mesh["faces_before_simplification"]  # fast-simplification through trimesh ran
    assert main(["report", str(run)]) == 0
    assert (run / "report.html").is_file()


@pytest.fixture(scope="module")
def arc_photos():
    return photos.arc_photos()


def test_process_data_images(arc_photos, tmp_path, capsys, monkeypatch):
    # One thread: COLMAP's matching and mapping are then deterministic for a seed (with two, the mapper
    # occasionally split these 10 photos into separate models).
    monkeypatch.setattr("nerfkit.process.sfm.SfmOptions", functools.partial(SfmOptions, threads=1))
    (tmp_path / "photos").mkdir()
    for k, rgb in enumerate(arc_photos):
        iio.imwrite(tmp_path / "photos" / f"p{k:02d}.png", rgb)
    out = tmp_path / "capture"
    assert main(["process-data", "images", str(tmp_path / "photos"), "--out", str(out), "--no-progress"]) == 0
    n = len(arc_photos)
    assert f"registered {n} of {n} photos" in capsys.readouterr().out
    assert len(json.loads((out / "transforms.json").read_text())["frames"]) == n


@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")  # imageio-ffmpeg forks ffmpeg, which execs at once
def test_process_data_video_with_the_opencv_lens(arc_photos, tmp_path, capsys):
    # imageio-ffmpeg both ways, sequential matching and the OPENCV bundle adjustment.
    iio.imwrite(tmp_path / "arc.mp4", np.stack(arc_photos), fps=10, codec="libx264", quality=10, macro_block_size=1)
    out = tmp_path / "capture"
    assert main(["process-data", "video", str(tmp_path / "arc.mp4"), "--frames", str(len(arc_photos)), "--out",
                 str(out), "--camera-model", "OPENCV", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "registered" in printed
    frames = json.loads((out / "transforms.json").read_text())
    assert frames["camera_model"] == "OPENCV" and len(frames["frames"]) >= 3
