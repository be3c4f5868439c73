"""Tests for atomic msgpack checkpoints (nerfkit.training.checkpoint)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from nerfkit.core.config import FieldConfig
from nerfkit.core.errors import CheckpointError
from nerfkit.training.checkpoint import (
    checkpoint_path,
    latest_checkpoint,
    list_checkpoints,
    read_checkpoint,
    restore_checkpoint,
    save_checkpoint,
)

FIELD = dataclasses.asdict(FieldConfig(depth=2, width=8))


def make_state(seed=0, steps=3):
    """params + adam state after a few updates (non-trivial moments and count)."""
    rng = np.random.default_rng(seed)
    params = {
        "trunk": [{"w": jnp.asarray(rng.normal(size=(3, 8)), jnp.float32), "b": jnp.zeros(8)}],
        "sigma": {"w": jnp.asarray(rng.normal(size=(8, 1)), jnp.float32), "b": jnp.asarray([0.1], jnp.float32)},
    }
    opt = optax.adam(1e-2)
    opt_state = opt.init(params)
    for _ in range(steps):
        grads = jax.tree_util.tree_map(lambda p: jnp.asarray(rng.normal(size=p.shape), p.dtype), params)
        updates, opt_state = opt.update(grads, opt_state, params)
        params = optax.apply_updates(params, updates)
    return {"params": params, "opt_state": opt_state}


def template(state):
    """Same structure, different values: restore must overwrite every leaf."""
    return jax.tree_util.tree_map(lambda x: jnp.zeros_like(x) - 7, state)


def test_round_trip_is_bit_exact(tmp_path):
    state = make_state()
    path = save_checkpoint(tmp_path, 42, state, FIELD, keep=3)
    assert path == checkpoint_path(tmp_path, 42) and path.name == "ckpt_00000042.msgpack"
    step, restored = restore_checkpoint(path, template(state), FIELD)
    assert step == 42
    assert jax.tree_util.tree_structure(restored) == jax.tree_util.tree_structure(state)
    leaves_a = jax.tree_util.tree_leaves(state)
    leaves_b = jax.tree_util.tree_leaves(restored)
    assert len(leaves_a) == len(leaves_b) >= 7
    for a, b in zip(leaves_a, leaves_b):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)
    # The adam step count survived (an int leaf), as did the nested namedtuple state.
    assert int(restored["opt_state"][0].count) == 3
    np.testing.assert_array_equal(np.asarray(restored["opt_state"][0].mu["sigma"]["w"]),
                                  np.asarray(state["opt_state"][0].mu["sigma"]["w"]))
    raw = read_checkpoint(path)
    assert raw["step"] == 42 and raw["field"] == FIELD


def test_keep_n_keeps_the_newest(tmp_path):
    state = make_state(steps=0)
    for step in (5, 10, 100, 1000, 20000):
        save_checkpoint(tmp_path, step, state, FIELD, keep=2)
    assert [p.name for p in list_checkpoints(tmp_path)] == ["ckpt_00001000.msgpack", "ckpt_00020000.msgpack"]
    assert latest_checkpoint(tmp_path) == checkpoint_path(tmp_path, 20000)
    save_checkpoint(tmp_path, 20001, state, FIELD, keep=1)
    assert list_checkpoints(tmp_path) == [checkpoint_path(tmp_path, 20001)]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ckpt_00020001.msgpack"]  # no temp files left


def test_latest_checkpoint_of_empty_or_missing_dir(tmp_path):
    assert latest_checkpoint(tmp_path) is None
    assert latest_checkpoint(tmp_path / "missing") is None


def test_truncated_checkpoint_raises(tmp_path):
    state = make_state()
    path = save_checkpoint(tmp_path, 1, state, FIELD, keep=3)
    blob = path.read_bytes()
    for cut in (len(blob) // 2, len(blob) - 1, 10):
        path.write_bytes(blob[:cut])
        with pytest.raises(CheckpointError, match="ckpt_00000001"):
            restore_checkpoint(path, template(state), FIELD)


def test_random_bytes_raise(tmp_path):
    state = make_state()
    path = checkpoint_path(tmp_path, 3)
    rng = np.random.default_rng(0)
    for n in (1, 7, 1000):
        path.write_bytes(rng.bytes(n))
        with pytest.raises(CheckpointError, match="ckpt_00000003"):
            restore_checkpoint(path, template(state), FIELD)
    path.write_bytes(b"")
    with pytest.raises(CheckpointError):
        read_checkpoint(path)


def test_missing_file_raises(tmp_path):
    with pytest.raises(CheckpointError, match="ckpt_00000009"):
        read_checkpoint(checkpoint_path(tmp_path, 9))


def test_different_field_config_raises_naming_the_key(tmp_path):
    state = make_state()
    path = save_checkpoint(tmp_path, 7, state, FIELD, keep=3)
    other = {**FIELD, "width": 16}
    with pytest.raises(CheckpointError, match=r"width: checkpoint 8 vs config 16") as e:
        restore_checkpoint(path, template(state), other)
    assert "depth" not in str(e.value)  # only the differing key is named
    with pytest.raises(CheckpointError, match="l_xyz"):
        restore_checkpoint(path, template(state), {**FIELD, "l_xyz": 3})


def test_structure_or_shape_mismatch_raises(tmp_path):
    state = make_state()
    path = save_checkpoint(tmp_path, 7, state, FIELD, keep=3)
    wider = jax.tree_util.tree_map(lambda x: jnp.zeros((*x.shape[:-1], x.shape[-1] + 1)) if x.ndim else x, state)
    with pytest.raises(CheckpointError, match="shape"):
        restore_checkpoint(path, wider, FIELD)
    extra = {**state, "params": {**state["params"], "rgb": {"w": jnp.zeros((8, 3))}}}
    with pytest.raises(CheckpointError):
        restore_checkpoint(path, extra, FIELD)


def test_leftover_temporary_file_is_ignored(tmp_path):
    state = make_state(steps=0)
    save_checkpoint(tmp_path, 5, state, FIELD, keep=3)
    # A write of step 9 killed before its rename: garbage under the temporary name.
    (tmp_path / ".ckpt_00000009.msgpack.tmp-123").write_bytes(b"half a checkpoint")
    (tmp_path / "ckpt_00000009.msgpack.tmp-123").write_bytes(b"half a checkpoint")
    assert latest_checkpoint(tmp_path) == checkpoint_path(tmp_path, 5)
    assert list_checkpoints(tmp_path) == [checkpoint_path(tmp_path, 5)]
    step, _ = restore_checkpoint(latest_checkpoint(tmp_path), template(state), FIELD)
    assert step == 5
    # Later saves neither trip over nor count the leftover.
    save_checkpoint(tmp_path, 6, state, FIELD, keep=1)
    assert list_checkpoints(tmp_path) == [checkpoint_path(tmp_path, 6)]
