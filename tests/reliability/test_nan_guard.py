"""Item 4: a non-finite loss or gradient is not applied, is reported with its step, and a
streak of them stops the run with the last good checkpoint intact."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import load_blender

from nerfkit.core.errors import NerfkitError
from nerfkit.core.presets import preset
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models.nerf import NeRFModel
from nerfkit.run.folder import RunFolder
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training import trainer as train_mod
from nerfkit.training.step import init_state, make_optimizer, make_train_step
from nerfkit.training.trainer import Trainer


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("nan") / "scene", size=16, n_train=4, n_val=1, n_test=0, seed=3)


class PoisonModel(NeRFModel):
    """The tiny MLP model, except that a batch with a target value of 2.0 gets a finite loss
    but NaN gradients (sqrt(|x - x|) has an infinite slope at 0). Clean batches: unchanged."""

    @staticmethod
    def losses(out, target):
        loss, parts = NeRFModel.losses(out, target)
        zero = out["rgb"][0, 0] - out["rgb"][0, 0]
        extra = jax.lax.cond(jnp.any(target > 1.5), lambda z: jnp.sqrt(jnp.abs(z)), lambda z: 0.0 * z, zero)
        return loss + extra, parts


def _cfg(steps: int, max_bad: int = 5):
    c = preset("tiny")
    c.data.train_split, c.data.val_split = "train", "val"
    c.train.max_steps, c.train.val_every, c.train.ckpt_every, c.train.log_every = steps, 1000, 1000, 2
    c.train.max_bad_steps = max_bad
    return c


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree_util.tree_leaves(tree)]


def _same(a, b) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(_leaves(a), _leaves(b)))


def test_bad_step_is_not_applied(scene, compile_cache):
    """Step level: a NaN loss, and a finite loss with a NaN gradient, leave params and Adam state untouched."""
    cfg = _cfg(6)  # the run-level test's config: one compiled step for both tests
    data = load_blender(scene, "train")
    model = PoisonModel(cfg)
    optimizer, _ = make_optimizer(cfg)
    step_fn = make_train_step(model, optimizer, data, cfg)
    clean = jnp.asarray(data.images)
    nan_loss = clean.at[:].set(jnp.nan)
    nan_grad = clean.at[:].set(2.0)
    poses = jnp.asarray(data.poses)

    state = init_state(model, optimizer, cfg.train.seed)
    for step, (images, good) in enumerate([(clean, True), (nan_loss, False), (clean, True), (nan_grad, False),
                                           (nan_grad, False), (clean, True)]):
        before = jax.tree_util.tree_map(np.array, state)  # host copies: the state is donated
        state, m = step_fn(state, jnp.int32(step), images, poses)
        assert bool(m["finite"]) == good, step
        if images is nan_grad:
            assert np.isfinite(float(m["loss"]))  # the gradient alone trips the guard
        if good:
            assert np.isfinite(float(m["loss"]))
            assert not _same(state["params"], before["params"]), f"step {step}: good update not applied"
        else:
            assert _same(state["params"], before["params"]), f"step {step}: bad update applied"
            assert _same(state["opt_state"], before["opt_state"]), f"step {step}: optimizer state changed"
        assert all(np.all(np.isfinite(x)) for x in _leaves(state["params"]))
    assert int(state["opt_state"][0].count) == 3  # only the three good steps counted


def test_run_reports_isolated_bad_steps_and_stops_on_a_streak(scene, tmp_path, capsys, monkeypatch, compile_cache):
    monkeypatch.setattr(train_mod, "build_model", PoisonModel)
    run = tmp_path / "run"
    Trainer(scene, run, _cfg(6), progress=False).run()

    # One NaN pixel: the steps whose random batch draws it are bad, the others are not. Isolated
    # bad steps are reported and skipped, and the run goes on.
    capsys.readouterr()
    t = Trainer(scene, run, _cfg(40), resume=True, progress=False)
    t.train_data.images[1, 5, 7, 0] = np.nan
    res = t.run()
    out = capsys.readouterr().out
    bad = [int(line.split()[1].rstrip(":")) for line in out.splitlines() if "non-finite" in line]
    assert res.step == 40 and bad, out
    assert all(6 < s <= 40 for s in bad) and "update skipped" in out
    run_ = RunFolder(run).load()
    params40, step = run_.params, run_.step
    assert step == 40 and all(np.all(np.isfinite(x)) for x in _leaves(params40))
    good_ckpt = ckpt_lib.latest_checkpoint(run / "checkpoints")
    good_bytes = good_ckpt.read_bytes()

    # Every batch has finite loss but NaN gradients: every step is bad; after max_bad_steps in a
    # row the run stops.
    t = Trainer(scene, run, _cfg(80, max_bad=4), resume=True, progress=False)
    t.train_data.images[:] = 2.0
    with pytest.raises(NerfkitError, match=r"4 non-finite steps in a row \(last at step 44\)") as e:
        t.run()
    assert "checkpoint" in str(e.value) and "\n" not in str(e.value)
    out = capsys.readouterr().out
    for s in (41, 42, 43, 44):
        assert f"step {s}: non-finite loss or gradient" in out
    # The last good checkpoint is intact and still the newest.
    assert ckpt_lib.latest_checkpoint(run / "checkpoints") == good_ckpt
    assert good_ckpt.read_bytes() == good_bytes
    run_ = RunFolder(run).load()
    params, step = run_.params, run_.step
    assert step == 40
    assert _same(params, params40)
