"""A small fast-field run on the procedural scene, shared by the export and bake tests (trained once
per test session): 24 views at 64 px, 400 steps of at most 2^15 samples (half the demo preset's: 0.6x the
time per step, and no worse a field here: validation 22.6 vs 22.0 dB, the export and bake tests' measures
within their margins either way).

Its copy "moved" records, as its pose normalisation, a capture frame moved by a known
similarity S (rotation, scale 2.5, shift), as `nerfkit train` does for photo captures: an
export is right only if it lands in that frame, where S^-1 maps it back onto the scene.
"""

from __future__ import annotations

import json
import shutil

import numpy as np

from nerfkit.core.presets import preset
from nerfkit.data.procedural.scene import make_scene
from nerfkit.training.trainer import Trainer

SIZE = 64  # training images, pixels
STEPS = 400
SCALE = 2.5


def similarity() -> np.ndarray:
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    s = np.eye(4)
    s[:3, :3], s[:3, 3] = SCALE * q, [1.0, -4.0, 2.5]
    return s


def train_scene(root):
    """Train the run into root/run and make its moved copy root/moved (shared_run reads them)."""
    scene = make_scene(root / "scene", size=SIZE, n_train=24, n_val=2, n_test=2)
    cfg = preset("demo")
    cfg.field.hash_log2_size = 14
    cfg.train.max_steps, cfg.train.val_every, cfg.train.val_views, cfg.train.ckpt_every = STEPS, 10_000, 1, 10_000
    cfg.train.max_minutes = None  # the steps alone: a loaded machine must not cut the run short
    cfg.train.batch_rays, cfg.sampler.max_samples = 2048, 1 << 15  # ~790 rays of ~45 samples per step
    Trainer(scene, root / "run", cfg, progress=False).run()
    moved = root / "moved"
    shutil.copytree(root / "run", moved)
    info = json.loads((moved / "scene.json").read_text())
    info["transform"] = np.linalg.inv(similarity()).tolist()  # capture x_c = S x_n, so M = S^-1
    (moved / "scene.json").write_text(json.dumps(info))


def shared_run(root):
    """(run folder, a copy whose capture frame is moved by S, the training poses) of a root train_scene filled."""
    frames = json.loads((root / "scene" / "transforms_train.json").read_text())["frames"]
    poses = np.array([f["transform_matrix"] for f in frames])
    return root / "run", root / "moved", poses
