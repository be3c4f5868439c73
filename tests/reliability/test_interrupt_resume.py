"""Item 3: SIGINT / SIGTERM stop a run cleanly, and --resume continues it exactly.

A real `python -m nerfkit train` process on a tiny procedural scene is interrupted with
SIGINT part-way, resumed with the command its message prints, interrupted again with
SIGTERM, and resumed to the end. The final parameters and optimizer state must equal
those of an uninterrupted run of the same number of steps (the RNG of step s is
fold_in(PRNGKey(seed), s)). A second test resumes a model whose non-trainable state is a
real occupancy grid (nerfkit.sampling.occupancy) and checks the grid is restored, not rebuilt.
"""

from __future__ import annotations

import json
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.core.presets import preset
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models.nerf import NeRFModel
from nerfkit.run.folder import RunFolder
from nerfkit.sampling.occupancy import OccupancyConfig, init_occupancy, update_occupancy
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training import trainer as train_mod
from nerfkit.training.trainer import Trainer

N = 60
ARGS = ["--preset", "tiny", "--no-progress", "--max-steps", str(N), "--log-every", "2", "--val-every", "1000",
        "--ckpt-every", "30", "--train-split", "train", "--val-split", "val"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("resume") / "scene", size=16, n_train=4, n_val=1, n_test=0, seed=2)


def _rows(run: Path) -> list[dict]:
    path = run / "metrics.jsonl"
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:  # a line being written
            pass
    return rows


def _interrupt(cmd: list[str], run: Path, sig: int, after_step: int, env: dict) -> tuple[int, str, str]:
    """Start cmd, send `sig` once metrics.jsonl shows a step > after_step; (returncode, stdout, stderr)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 120
        while not any(r["step"] > after_step for r in _rows(run)):
            assert proc.poll() is None, f"run ended before it could be interrupted: {proc.communicate()}"
            assert time.monotonic() < deadline, "no training progress within 120 s"
            time.sleep(0.01)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out, err


def _raw_state(run: Path) -> tuple[int, dict]:
    raw = ckpt_lib.read_checkpoint(ckpt_lib.latest_checkpoint(run / "checkpoints"))
    state = dict(raw["state"])
    state.pop("elapsed")
    return raw["step"], state


def _assert_trees_close(a, b, atol=1e-6):
    la, lb = jax.tree_util.tree_leaves_with_path(a), jax.tree_util.tree_leaves_with_path(b)
    assert [p for p, _ in la] == [p for p, _ in lb]
    assert len(la) > 0
    for (path, x), (_, y) in zip(la, lb):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=0, atol=atol, err_msg=jax.tree_util.keystr(path))


def test_sigint_sigterm_and_resume_match_a_straight_run(scene, tmp_path, cached_env, compile_cache):
    run = tmp_path / "interrupted"
    cmd = [sys.executable, "-m", "nerfkit", "train", str(scene), "--out", str(run), *ARGS]

    # 1. SIGINT: finish the step, save, exit 130 with a message saying how to resume.
    rc, out, err = _interrupt(cmd, run, signal.SIGINT, after_step=0, env=cached_env)
    assert rc == 130, (out, err)
    assert "SIGINT received" in err
    assert "--resume" in out and "Traceback" not in err
    step1, _ = _raw_state(run)
    assert 0 < step1 < N
    assert f"stopped at step {step1}" in out

    # 2. Resume with the printed command, then SIGTERM.
    lines = out.splitlines()
    resume = shlex.split(lines[[k for k, line in enumerate(lines) if "Resume with" in line][0] + 1])
    assert resume[0] == "nerfkit" and resume[-1] == "--resume"
    cmd2 = [sys.executable, "-m", *resume, "--no-progress"]
    rc, out, err = _interrupt(cmd2, run, signal.SIGTERM, after_step=step1, env=cached_env)
    assert rc == 130, (out, err)
    assert "SIGTERM received" in err and "resumed from" in out and "--resume" in out
    step2, _ = _raw_state(run)
    assert step1 < step2 < N

    # 3. Resume to the end (in-process, through the CLI).
    assert main(["train", str(scene), "--out", str(run), "--resume", "--no-progress"]) == 0

    # 4. The same N steps without interruption.
    straight = tmp_path / "straight"
    assert main(["train", str(scene), "--out", str(straight), *ARGS]) == 0

    run_ = RunFolder(run).load()

    params_a, aux_a, s_a = run_.params, run_.aux, run_.step
    run_ = RunFolder(straight).load()
    cfg_b, params_b, aux_b, s_b = run_.cfg, run_.params, run_.aux, run_.step
    assert s_a == s_b == N
    _assert_trees_close(params_a, params_b)
    # Optimizer state (Adam moments and count) too, from the raw checkpoints.
    _, raw_a = _raw_state(run)
    _, raw_b = _raw_state(straight)
    _assert_trees_close(raw_a, raw_b)
    # The logged losses agree step by step, and the resumed log has no duplicate or missing steps.
    rows_a, rows_b = _rows(run), _rows(straight)
    steps_a = [r["step"] for r in rows_a]
    assert steps_a == sorted(set(steps_a)) and steps_a[-1] == N
    loss_a = {r["step"]: r["loss"] for r in rows_a}
    for r in rows_b:
        assert loss_a[r["step"]] == pytest.approx(r["loss"], rel=1e-5, abs=1e-7), r["step"]


class GridModel(NeRFModel):
    """The tiny MLP model with a real occupancy grid as its non-trainable state (like the fast
    field): the grid is refreshed from the field's density every 3 steps."""

    OCC = OccupancyConfig(resolution=8, bound=1.5)

    def init(self, key):
        params, _ = super().init(key)
        return params, init_occupancy(self.OCC)

    def update_aux(self, params, aux, step, key):
        def update(a):
            return update_occupancy(a, lambda x: self.coarse.density(params["coarse"], x), key, step, self.OCC,
                                    warmup_steps=6, chunk_size=512)

        return jax.lax.cond(step % 3 == 0, update, lambda a: a, aux)


def test_resume_restores_the_occupancy_grid(scene, tmp_path, monkeypatch, compile_cache):
    monkeypatch.setattr(train_mod, "build_model", GridModel)

    def cfg(steps):
        c = preset("tiny")
        c.data.train_split, c.data.val_split = "train", "val"
        c.train.max_steps, c.train.val_every, c.train.ckpt_every, c.train.log_every = steps, 1000, 1000, 5
        return c

    split, total = 8, 16
    Trainer(scene, tmp_path / "a", cfg(split), progress=False).run()
    _, half = _raw_state(tmp_path / "a")
    assert int(half["aux"]["n_updates"]) == 3  # steps 0, 3, 6
    assert not np.all(half["aux"]["bits"])  # the grid has left its all-occupied initial state
    Trainer(scene, tmp_path / "a", cfg(total), resume=True, progress=False).run()
    Trainer(scene, tmp_path / "b", cfg(total), progress=False).run()
    step_a, state_a = _raw_state(tmp_path / "a")
    step_b, state_b = _raw_state(tmp_path / "b")
    assert step_a == step_b == total
    assert int(state_a["aux"]["n_updates"]) == 6  # steps 0, 3, ..., 15: counted across the resume
    np.testing.assert_array_equal(state_a["aux"]["bits"], state_b["aux"]["bits"])
    _assert_trees_close(state_a, state_b)
