"""Tests for the Blender-synthetic loader (nerfkit.data.formats.blender).

Most tests use a tiny procedurally generated scene (nerfkit.data.procedural.scene.make_scene); the
lego tests use the shared dataset when it is present and skip otherwise (fail in CI: shared_data.py).
"""

import json
import math
import shutil
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from reference import load_blender, read_split_poses
from shared_data import SHARED_DATA, require_shared

from nerfkit.core.errors import DataError
from nerfkit.data.formats.blender import SplitItem, parse_split_spec
from nerfkit.data.procedural.scene import make_scene

SIZE = 8
N_TRAIN, N_VAL = 3, 3
LEGO = SHARED_DATA / "nerf_synthetic" / "lego"


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"), size=SIZE, n_train=N_TRAIN, n_val=N_VAL, n_test=0, seed=1)


@pytest.fixture
def scene_copy(scene_dir, tmp_path):
    """A private copy to break on purpose."""
    return Path(shutil.copytree(scene_dir, tmp_path / "scene"))


def meta(root, split):
    return json.loads((root / f"transforms_{split}.json").read_text())


def png_rgba(root, split, k):
    return iio.imread(root / split / f"r_{k}.png").astype(np.float64) / 255.0


# --- loading ------------------------------------------------------------------------------


def test_shapes_focal_and_poses(scene_dir):
    data = load_blender(scene_dir, "train")
    assert len(data) == N_TRAIN
    assert data.images.shape == (N_TRAIN, SIZE, SIZE, 3) and data.images.dtype == np.float32
    assert data.poses.shape == (N_TRAIN, 4, 4) and data.poses.dtype == np.float32
    assert (data.height, data.width) == (SIZE, SIZE)
    fov = meta(scene_dir, "train")["camera_angle_x"]
    assert data.focal == pytest.approx(0.5 * SIZE / math.tan(0.5 * fov), rel=1e-12)
    expected = np.array([f["transform_matrix"] for f in meta(scene_dir, "train")["frames"]], np.float32)
    np.testing.assert_array_equal(data.poses, expected)
    assert data.names == [f"train/r_{k}.png" for k in range(N_TRAIN)]
    assert data.images.min() >= 0.0 and data.images.max() <= 1.0


def test_white_and_black_backgrounds_differ_by_one_minus_alpha(scene_dir):
    white = load_blender(scene_dir, "train", background="white")
    black = load_blender(scene_dir, "train", background="black")
    for k in range(N_TRAIN):
        rgba = png_rgba(scene_dir, "train", k)
        alpha = rgba[..., 3]
        assert alpha.min() == 0.0 and alpha.max() == 1.0  # both object and background pixels
        # rgb = a c + (1 - a) bg: white - black = (1 - a) exactly, up to float32 rounding.
        np.testing.assert_allclose(white.images[k] - black.images[k],
                                   np.broadcast_to((1 - alpha)[..., None], (SIZE, SIZE, 3)), atol=1e-6)
        np.testing.assert_allclose(black.images[k], rgba[..., :3] * alpha[..., None], atol=1e-6)


def test_downscale_two_is_block_mean(scene_dir):
    full = load_blender(scene_dir, "train")
    half = load_blender(scene_dir, "train", downscale=2)
    assert half.images.shape == (N_TRAIN, SIZE // 2, SIZE // 2, 3)
    assert (half.height, half.width) == (SIZE // 2, SIZE // 2)
    a = full.images.astype(np.float64)
    block = (a[:, 0::2, 0::2] + a[:, 1::2, 0::2] + a[:, 0::2, 1::2] + a[:, 1::2, 1::2]) / 4
    np.testing.assert_allclose(half.images, block, atol=1e-6)
    assert half.focal == pytest.approx(full.focal / 2, rel=1e-12)
    np.testing.assert_array_equal(half.poses, full.poses)
    # target_width picks the same factor.
    tw = load_blender(scene_dir, "train", target_width=SIZE // 2)
    np.testing.assert_array_equal(tw.images, half.images)


@pytest.mark.parametrize("kwargs", [{"downscale": 3}, {"target_width": 3}, {"target_width": 16}])
def test_downscale_that_does_not_divide_raises(scene_dir, kwargs):
    with pytest.raises(DataError, match="r_0.png"):
        load_blender(scene_dir, "train", **kwargs)


def test_split_spec_parsing():
    assert parse_split_spec("train,val[0:2]") == [SplitItem("train"), SplitItem("val", 0, 2)]
    assert parse_split_spec("val[1:]") == [SplitItem("val", 1, None)]
    assert parse_split_spec(" train , val[ -2 : ] ") == [SplitItem("train"), SplitItem("val", -2, None)]
    assert parse_split_spec("test[:5]") == [SplitItem("test", None, 5)]
    assert str(SplitItem("val", 1, None)) == "val[1:]"


@pytest.mark.parametrize("spec", ["", "   ", "train,", "train[0:2", "train[0]", "val[a:b]", "tr ain", "val[0:2:1]", "[0:2]"])
def test_bad_split_specs_raise_data_error(spec):
    with pytest.raises(DataError):
        parse_split_spec(spec)


@pytest.mark.parametrize("spec", ["val[-:2]", "val[0:-]"])
def test_lone_minus_in_split_spec_raises_data_error(spec):
    with pytest.raises(DataError):
        parse_split_spec(spec)


def test_load_split_spec_selects_frames(scene_dir):
    data = load_blender(scene_dir, "train,val[0:2]")
    assert len(data) == N_TRAIN + 2
    train, val = meta(scene_dir, "train")["frames"], meta(scene_dir, "val")["frames"]
    expected = [f["transform_matrix"] for f in train] + [f["transform_matrix"] for f in val[0:2]]
    np.testing.assert_array_equal(data.poses, np.array(expected, np.float32))
    assert data.names[-2:] == ["val/r_0.png", "val/r_1.png"]
    tail = load_blender(scene_dir, "val[1:]")
    assert tail.names == ["val/r_1.png", "val/r_2.png"]
    np.testing.assert_array_equal(tail.images, load_blender(scene_dir, "val").images[1:])
    last = load_blender(scene_dir, "val[-1:]")
    assert last.names == ["val/r_2.png"]
    poses, fov = read_split_poses(scene_dir, "val[1:]")
    np.testing.assert_array_equal(poses, tail.poses)
    assert fov == meta(scene_dir, "val")["camera_angle_x"]


@pytest.mark.parametrize("spec", ["val[0:4]", "val[4:]", "val[-4:]", "val[2:1]"])
def test_out_of_range_or_empty_selection_raises(scene_dir, spec):
    with pytest.raises(DataError, match="transforms_val.json"):
        load_blender(scene_dir, spec)


# --- broken data: every error names the file at fault -----------------------------------------


def test_missing_folder(tmp_path):
    with pytest.raises(DataError, match="nowhere"):
        load_blender(tmp_path / "nowhere", "train")


def test_missing_image(scene_copy):
    (scene_copy / "train" / "r_1.png").unlink()
    with pytest.raises(DataError, match=r"r_1\.png"):
        load_blender(scene_copy, "train")


def test_missing_json(scene_copy):
    (scene_copy / "transforms_val.json").unlink()
    with pytest.raises(DataError, match=r"transforms_val\.json") as e:
        load_blender(scene_copy, "train,val")
    assert "transforms_train.json" in str(e.value)  # the hint lists what is there


def test_bad_json(scene_copy):
    p = scene_copy / "transforms_train.json"
    p.write_text(p.read_text()[:-20])
    with pytest.raises(DataError, match=r"transforms_train\.json"):
        load_blender(scene_copy, "train")


def _edit_pose(root, k, fn):
    p = root / "transforms_train.json"
    m = json.loads(p.read_text())
    m["frames"][k]["transform_matrix"] = fn(np.array(m["frames"][k]["transform_matrix"])).tolist()
    p.write_text(json.dumps(m))


def test_non_finite_pose(scene_copy):
    p = scene_copy / "transforms_train.json"
    m = json.loads(p.read_text())
    m["frames"][1]["transform_matrix"][0][3] = float("nan")
    p.write_text(json.dumps(m))  # json writes NaN, which Python's json reads back
    with pytest.raises(DataError, match=r"transforms_train\.json frame 1.*non-finite"):
        load_blender(scene_copy, "train")


def _scale(m):
    m[:3, :3] *= 1.5
    return m


def _mirror(m):
    m[:3, 0] *= -1  # det -1: a reflection is not a rotation
    return m


@pytest.mark.parametrize("edit", [_scale, _mirror])
def test_non_rigid_pose(scene_copy, edit):
    _edit_pose(scene_copy, 2, edit)
    with pytest.raises(DataError, match=r"transforms_train\.json frame 2.*not rigid"):
        load_blender(scene_copy, "train")


def test_size_mismatch(scene_copy):
    img = iio.imread(scene_copy / "train" / "r_1.png")
    iio.imwrite(scene_copy / "train" / "r_1.png", np.concatenate([img, img], axis=1))
    with pytest.raises(DataError, match=r"r_1\.png"):
        load_blender(scene_copy, "train")


def test_truncated_png(scene_copy):
    p = scene_copy / "train" / "r_2.png"
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match=r"r_2\.png"):
        load_blender(scene_copy, "train")


def test_not_a_png(scene_copy):
    (scene_copy / "val" / "r_0.png").write_bytes(b"\x00not an image at all")
    with pytest.raises(DataError, match=r"r_0\.png"):
        load_blender(scene_copy, "val")


# --- the shared lego scene ----------------------------------------------------------------------


def _need_lego():
    require_shared(LEGO / "transforms_train.json")


def _lego_focal(width):
    fov = json.loads((LEGO / "transforms_train.json").read_text())["camera_angle_x"]
    return 0.5 * width / math.tan(0.5 * fov)


def test_lego_train_slice():
    _need_lego()
    data = load_blender(LEGO, "train[0:5]", downscale=2)
    assert data.images.shape == (5, 200, 200, 3)
    assert data.focal == pytest.approx(_lego_focal(200), rel=1e-12)
    assert data.focal == pytest.approx(277.8, abs=0.1)
    m = json.loads((LEGO / "transforms_train.json").read_text())
    np.testing.assert_array_equal(data.poses[0], np.array(m["frames"][0]["transform_matrix"], np.float32))
    np.testing.assert_array_equal(data.poses, np.array([f["transform_matrix"] for f in m["frames"][:5]], np.float32))
    # Downscale 2 is the block mean of the full-resolution image.
    full = load_blender(LEGO, "train[0:1]")
    assert full.images.shape[1:] == (400, 400, 3)
    block = full.images[0].astype(np.float64).reshape(200, 2, 200, 2, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(data.images[0], block, atol=1e-6)


def test_lego_full_train_split():
    _need_lego()
    data = load_blender(LEGO, "train", downscale=2)
    assert data.images.shape == (100, 200, 200, 3)
    assert data.poses.shape == (100, 4, 4)
    assert data.focal == pytest.approx(_lego_focal(200), rel=1e-12)
    assert np.isfinite(data.images).all() and data.images.min() >= 0 and data.images.max() <= 1
