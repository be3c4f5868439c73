"""mip-NeRF's multiscale layout: make-multiscale, the loader's per-frame intrinsics, eval per scale."""

from __future__ import annotations

import json
import shutil

import imageio.v3 as iio
import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.data.formats.multiscale import make_multiscale
from nerfkit.data.images import area_downscale
from nerfkit.data.loader import load_frames, read_capture
from nerfkit.data.procedural.scene import make_scene
from nerfkit.rays.cameras import camera_rays

LEVELS = 3


@pytest.fixture(scope="module")
def multiscale(tmp_path_factory):
    root = tmp_path_factory.mktemp("ms")
    src = make_scene(root / "scene", size=32, n_train=2, n_val=1, n_test=2)
    info = make_multiscale(src, out=root / "ms", levels=LEVELS, progress=False)
    return src, root / "ms", info


def test_metadata_has_mip_nerf_layout(multiscale):
    src, ms, info = multiscale
    meta = json.loads((ms / "metadata.json").read_text())
    assert sorted(meta) == ["test", "train", "val"] and info["images"] == 5 * LEVELS
    t = meta["test"]
    full = json.loads((src / "transforms_test.json").read_text())
    focal = 0.5 * 32 / np.tan(0.5 * full["camera_angle_x"])
    assert t["label"] == [0, 0, 1, 1, 2, 2]
    assert t["width"] == t["height"] == [32, 32, 16, 16, 8, 8]
    np.testing.assert_allclose(t["focal"], [focal, focal, focal / 2, focal / 2, focal / 4, focal / 4], rtol=1e-6)
    assert t["lossmult"] == [1.0, 1.0, 4.0, 4.0, 16.0, 16.0]
    np.testing.assert_allclose(t["cam2world"][3], full["frames"][1]["transform_matrix"])
    assert all((ms / p).is_file() for p in t["file_path"])


def test_each_level_is_the_box_average_of_the_full_image(multiscale):
    """Composited on white, a level-l pixel is the mean of the 2^l x 2^l full-resolution pixels it covers
    (colours were averaged with their alpha), up to 8-bit rounding."""
    _, ms, _ = multiscale
    cap = read_capture(ms, "test")
    full = load_frames(cap, "test_d0").images
    for lvl in range(1, LEVELS):
        small = load_frames(cap, f"test_d{lvl}").images
        want = np.stack([area_downscale(im, 2**lvl) for im in full])
        assert np.abs(small - want).max() <= 1.5 / 255


def test_a_coarse_pixel_sees_the_mean_ray_of_the_pixels_it_averages(multiscale):
    """Per-frame intrinsics: the ray through the centre of pixel (i, j) at level 1 is the mean of the rays
    through pixels (2i..2i+1, 2j..2j+1) at level 0 (pinhole rays are affine in pixel coordinates)."""
    _, ms, _ = multiscale
    cap = read_capture(ms, "val")
    frames = cap.frames("val")
    assert [f.camera.width for f in frames] == [32, 16, 8]
    o0, d0 = camera_rays(frames[0].c2w, frames[0].camera)
    o1, d1 = camera_rays(frames[1].c2w, frames[1].camera)
    mean = d0.reshape(16, 2, 16, 2, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(d1, mean, atol=1e-6)
    np.testing.assert_allclose(o1[0, 0], o0[0, 0])


def test_a_slice_selects_views_at_every_level(multiscale):
    _, ms, _ = multiscale
    cap = read_capture(ms, "test")
    picked = cap.frames("test[1:2]")
    assert [f.image.name for f in picked] == ["r_1_d0.png", "r_1_d1.png", "r_1_d2.png"]
    assert [f.image.name for f in cap.frames("test_d2")] == ["r_0_d2.png", "r_1_d2.png"]


def test_eval_reports_every_scale(procedural_run, tmp_path, capsys):
    run = procedural_run[0]
    scene = json.loads((run / "scene.json").read_text())["data_dir"]
    make_multiscale(scene, tmp_path / "ms", 4, progress=False)
    assert main(["eval", str(run), "--data", str(tmp_path / "ms"), "--split", "test"]) == 0
    res = json.loads((run / "eval_test_multiscale.json").read_text())
    assert [s["width"] for s in res["scales"]] == [64, 32, 16, 8]
    assert res["psnr"] == pytest.approx(np.mean([s["psnr"] for s in res["scales"]]))
    assert len(res["per_view"]) == 8 and (run / "eval_test_multiscale" / "d3" / "view_001.png").is_file()
    out = capsys.readouterr().out
    assert " d3 " in out and "eval_test_multiscale.json" in out


@pytest.mark.parametrize("args, match", [
    (["make-multiscale", "{tmp}", "--out", "{tmp}/ms"], "no transforms_*.json"),
    (["make-multiscale", "{scene}", "--out", "{scene}"], "exists and is not an empty folder"),
    (["make-multiscale", "{scene}", "--out", "{tmp}/ms", "--levels", "0"], "--levels must be between 1 and 8"),
    (["make-multiscale", "{scene}", "--out", "{tmp}/ms", "--levels", "7"], "not divisible by 64"),
])
def test_bad_make_multiscale_arguments_are_one_line_errors(multiscale, tmp_path, capsys, args, match):
    argv = [a.format(tmp=tmp_path, scene=multiscale[0]) for a in args] + ["--no-progress"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert match in err and len(err.splitlines()) == 1


def test_an_image_refused_half_way_leaves_no_folder(multiscale, tmp_path, capsys):
    """An odd-sized photo in the last split (val) is refused after the other splits' levels are written: one line,
    exit 1, and --out does not appear (so the same command is not then refused as a folder that is not empty)."""
    src = tmp_path / "scene"
    shutil.copytree(multiscale[0], src)
    iio.imwrite(src / "val" / "r_0.png", iio.imread(src / "val" / "r_0.png")[:31, :31])
    assert main(["make-multiscale", str(src), "--out", str(tmp_path / "ms"), "--levels", "2", "--no-progress"]) == 1
    err = capsys.readouterr().err.strip()
    assert "31x31 is not divisible by 2" in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene"]


def test_training_draws_every_scale_with_area_weights(multiscale, tmp_path):
    """Training on a multiscale split: the images keep their sizes (padded in one array, cropped by
    image(k)), each level's loss weight is its pixel area, and a short run trains and validates."""
    from nerfkit.core.presets import preset
    from nerfkit.training.trainer import Trainer

    _, ms, _ = multiscale
    cfg = preset("demo")
    cfg.field.hash_log2_size, cfg.field.hash_levels = 12, 4  # 4 levels: a third of the compile time of 16
    cfg.data.train_split, cfg.data.val_split = "train", "val"
    cfg.train.max_steps, cfg.train.val_every, cfg.train.val_views, cfg.train.ckpt_every = 30, 10_000, 3, 10_000
    cfg.train.batch_rays = 512
    trainer = Trainer(ms, tmp_path / "run", cfg, progress=False)
    td = trainer.train_data
    assert [tuple(s) for s in td.sizes] == [(32, 32)] * 2 + [(16, 16)] * 2 + [(8, 8)] * 2
    np.testing.assert_allclose(td.lossmult, [1, 1, 4, 4, 16, 16])
    assert td.image(4).shape == (8, 8, 3) and np.all(td.images[4, 8:] == 0)
    result = trainer.run()
    losses = [json.loads(line)["loss"] for line in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert result.step == 30 and np.all(np.isfinite(losses)) and result.val_psnr > 5


def test_weighted_losses_are_the_weighted_mean_square_error():
    import jax.numpy as jnp

    from nerfkit.models.nerf import NeRFModel
    from nerfkit.models.ngp import NGPModel

    target = jnp.zeros((3, 3))
    out = {"rgb": jnp.array([[1.0, 1, 1], [0.5, 0.5, 0.5], [0.0, 0, 0]]), "complete": jnp.array([True, True, False])}
    w = jnp.array([1.0, 4.0, 16.0])
    assert float(NeRFModel.losses(out, target, w)[0]) == pytest.approx((1 + 4 * 0.25) / 21)
    assert float(NGPModel.losses(out, target, w)[0]) == pytest.approx((1 + 4 * 0.25) / 5)  # incomplete ray dropped
