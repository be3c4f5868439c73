"""The training loop's callbacks (training/callbacks.py): the hooks are called when their docstring says, the
checkpoints are a callback (a loop without it writes none), and a callback of one's own joins with no other edit."""

from __future__ import annotations

import pytest

from nerfkit.core.presets import preset
from nerfkit.data.procedural.scene import make_scene
from nerfkit.training.callbacks import Callback, Checkpoints, ProgressBar
from nerfkit.training.trainer import Trainer


class Recorder(Callback):
    """Notes every hook call: (hook, loop.step)."""

    def __init__(self):
        self.calls = []

    def begin(self, trainer, loop, state):
        self.calls.append(("begin", loop.step))

    def after_step(self, trainer, loop, state):
        assert set(state) >= {"params", "aux"}
        self.calls.append(("after_step", loop.step))

    def after_log(self, trainer, loop, row):
        assert row["step"] == loop.step and {"loss", "psnr"} <= set(row)
        self.calls.append(("after_log", loop.step))

    def end(self, trainer, loop, state, interrupted):
        self.calls.append(("end", loop.step, interrupted))


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("cb") / "scene", size=16, n_train=6, n_val=2, n_test=1, seed=3)


def _trainer(scene, run, steps=12):
    cfg = preset("tiny")
    cfg.field.depth, cfg.field.width, cfg.sampler.n_samples = 2, 16, 8
    cfg.train.max_steps, cfg.train.max_minutes, cfg.train.batch_rays = steps, None, 64
    cfg.train.log_every, cfg.train.ckpt_every, cfg.train.val_every = 4, 5, 1000
    return Trainer(scene, run, cfg, progress=False)


def test_hooks_run_in_order_and_checkpoints_are_a_callback(scene, tmp_path):
    trainer = _trainer(scene, tmp_path / "run")
    assert [type(c) for c in trainer.callbacks] == [ProgressBar, Checkpoints]
    rec = Recorder()
    trainer.callbacks.append(rec)
    trainer.run()
    assert rec.calls[0] == ("begin", 0) and rec.calls[-1] == ("end", 12, False)
    assert [s for h, s, *_ in rec.calls if h == "after_step"] == list(range(1, 13))
    assert [s for h, s, *_ in rec.calls if h == "after_log"] == [4, 8, 12]
    # every 5 steps and at the end (the newest --keep-ckpts 3)
    saved = sorted(p.name for p in (tmp_path / "run" / "checkpoints").glob("ckpt_*.msgpack"))
    assert saved == [f"ckpt_{s:08d}.msgpack" for s in (5, 10, 12)]


def test_a_loop_without_the_checkpoint_callback_writes_none(scene, tmp_path):
    trainer = _trainer(scene, tmp_path / "run", steps=6)
    trainer.callbacks = [c for c in trainer.callbacks if not isinstance(c, Checkpoints)]
    trainer.run()
    assert (tmp_path / "run" / "metrics.jsonl").is_file()
    assert not list((tmp_path / "run").glob("checkpoints/*.msgpack"))
