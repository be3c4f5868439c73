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


def test_large_photos_are_validated_smaller_and_the_log_says_so(tmp_path, capsys, monkeypatch):
    import numpy as np

    from nerfkit.training import trainer as trainer_module
    from nerfkit.training.validation import validation_factor

    assert validation_factor(1368, 770) == 3 and (1368 // 3) * (770 // 3) <= 1 << 17  # buddha: 456x256
    assert validation_factor(200, 200) == 1 and validation_factor(432, 432) == 2
    monkeypatch.setattr(trainer_module, "validation_factor", lambda w, h: 2)  # the scene's 16 px views: shrunk 2x
    scene = make_scene(tmp_path / "scene", size=16, n_train=3, n_val=1, n_test=0)
    cfg = preset("tiny")
    cfg.train.max_steps, cfg.train.val_every, cfg.train.ckpt_every = 2, 2, 2
    run = tmp_path / "run"
    Trainer(scene, run, cfg, progress=True).run()
    out = capsys.readouterr().out
    assert "at 8x8 (1/2 of the photos' size" in out and "scores all 1 at full size" in out
    row = read_jsonl(run / "val_metrics.jsonl")[-1]
    assert row["step"] == 2 and row["seconds"] > 0
    assert np.load(run / "val" / "step_0000002" / "view_000_depth.npy").shape == (8, 8)
