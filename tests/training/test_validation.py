"""Periodic validation stays within --val-max-fraction of the wall time."""

import time

import pytest

from nerfkit.core.presets import preset
from nerfkit.core.viz import read_jsonl
from nerfkit.data.procedural.scene import make_scene
from nerfkit.training.trainer import Trainer

STEPS = 20


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("val") / "scene", size=8, n_train=4, n_val=2, n_test=0)


@pytest.mark.parametrize("fraction", [0.1, 1.0])
def test_validation_share_of_wall_time_is_bounded(scene, tmp_path, monkeypatch, fraction):
    real = Trainer.validate

    def slow_validate(self, state, step, elapsed):
        time.sleep(0.2)  # a validation far slower than a step
        return real(self, state, step, elapsed)

    monkeypatch.setattr(Trainer, "validate", slow_validate)
    cfg = preset("tiny")
    cfg.train.max_steps, cfg.train.val_every, cfg.train.ckpt_every = STEPS, 1, STEPS
    cfg.train.val_max_fraction = fraction
    t0 = time.perf_counter()
    Trainer(scene, tmp_path / "run", cfg, progress=False).run()
    wall = time.perf_counter() - t0
    rows = read_jsonl(tmp_path / "run" / "val_metrics.jsonl")
    if fraction == 1.0:
        assert len(rows) == STEPS  # every step, as --val-every 1 asks
    else:
        # Each validation (>= 0.2 s) buys >= 1.8 s of training before the next one, and the last step
        # is always validated: far fewer than STEPS, and at most ~10% of the time beyond the final one.
        assert 2 <= len(rows) <= 2 + wall / 1.8, (len(rows), wall)
        assert rows[-1]["step"] == STEPS
