"""Settings that come from the data (training/resolve.py): the splits and the scene type, each with the
reason it prints (the numbers it fills in, box and near/far: tests/models/test_unbounded.py)."""

from pathlib import Path

import numpy as np

from nerfkit.core.presets import preset
from nerfkit.data.capture import Capture, Frame
from nerfkit.rays.cameras import Camera
from nerfkit.training.resolve import default_splits, scene_type


def _capture(fmt: str, masks: bool = False, hint: str | None = None) -> Capture:
    frame = Frame(Path("a.png"), np.eye(4), Camera.pinhole(8, 8, 8.0), Path("a_mask.png") if masks else None)
    return Capture(Path("."), fmt, {"train": [frame]}, hint=hint)


def test_splits_default_to_val_or_test():
    cfg = preset("ngp")
    assert default_splits(cfg, ["train", "val", "test"]) == ("train", "val")
    assert default_splits(cfg, ["train", "test", "all"]) == ("train", "test")
    cfg.data.train_split, cfg.data.val_split = "train,val[0:50]", "val[50:100]"
    assert default_splits(cfg, ["train", "val"]) == ("train,val[0:50]", "val[50:100]")


def test_scene_type_from_the_capture():
    cfg = preset("ngp")
    assert scene_type(cfg, _capture("blender")) == ("bounded", "Blender scene")
    assert scene_type(cfg, _capture("llff", masks=True)) == ("bounded", "masked capture")
    assert scene_type(cfg, _capture("nerfstudio", hint="bounded")) == ("bounded", "aabb_scale 1")
    assert scene_type(cfg, _capture("colmap")) == ("unbounded", "photos without masks")
    cfg.field.scene_type = "bounded"
    assert scene_type(cfg, _capture("colmap")) == ("bounded", "--scene-type")
