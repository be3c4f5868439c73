"""A toy method and a toy capture format, written as a contributor would add real ones: each is one
self-contained definition following its seam (models/base.py, data/formats/registry.py); registering
each is one line (tests/test_extension.py)."""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.data.capture import Capture, Frame, holdout_splits
from nerfkit.data.images import image_size
from nerfkit.models.base import Supports
from nerfkit.rays.cameras import Camera


class ConstantColour:
    """The simplest RayModel: every ray is one colour c = sigmoid(p), p [3] the only parameter. Trained on
    MSE, c converges to the mean colour of the training pixels (the minimiser of sum (c - y)^2)."""

    supports = Supports(family="rays", parallel="rays", mesh=False)
    title = "toy"
    reads = frozenset({"train.lr", "train.lr_decay_steps", "train.lr_decay_rate", "train.batch_rays", "train.chunk"})

    def __init__(self, cfg):
        self.cfg = cfg
        self.rays_per_step = cfg.train.batch_rays
        self.loss_name = "MSE"

    @staticmethod
    def describe(cfg) -> str:
        return "toy: one colour for every ray"

    def init(self, key):
        return {"logit": jnp.zeros(3, jnp.float32)}, {}

    def update_aux(self, params, aux, step, key):
        return aux

    def render_rays(self, params, aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        n = o.shape[0]
        rgb = jnp.broadcast_to(jax.nn.sigmoid(params["logit"]), (n, 3))
        far = jnp.full((n,), 1.0, jnp.float32)
        return {"rgb": rgb, "depth": far, "depth_normalized": far, "opacity": jnp.ones((n,), jnp.float32)}

    @staticmethod
    def losses(out: dict, target, weights=None):
        mse = jnp.mean((out["rgb"] - target) ** 2)
        return mse, {"mse": mse}


class ToyFormat:
    """A capture format: toy.json = {"focal": f, "frames": [{"file": "x.png", "c2w": [4][4]}, ...]}
    (OpenGL camera-to-world, pinhole cameras); every 4th frame is held out as test."""

    NAME = "toy"
    LOOKS_FOR = "toy.json"

    @staticmethod
    def detect(root: Path) -> bool:
        return (Path(root) / "toy.json").is_file()

    @staticmethod
    def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
        root = Path(root)
        meta = json.loads((root / "toy.json").read_text())
        frames = []
        for k, f in enumerate(meta["frames"]):
            path = root / f["file"]
            w, h = image_size(path)
            frames.append(Frame(path, np.asarray(f["c2w"], np.float64), Camera.pinhole(w, h, meta["focal"]),
                                None, f"{root / 'toy.json'} frame {k}"))
        return Capture(root, "toy", holdout_splits(frames, 4), normalize=False, alpha=True)
