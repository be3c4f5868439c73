"""Item 5: safe loading. No pickle anywhere; a corrupted, truncated, foreign or damaged
checkpoint gives a clear one-line error; one from another model says what differs.

Complements tests/training/test_checkpoint.py (truncation, random bytes, field-config mismatch,
shape mismatch, leftover temporaries).
"""

from __future__ import annotations

import ast
import dataclasses
import os
import pickle
from pathlib import Path

import jax
import msgpack
import numpy as np
import pytest

from nerfkit.core.errors import CheckpointError
from nerfkit.core.presets import preset
from nerfkit.models.nerf import NeRFModel
from nerfkit.training.checkpoint import (
    checkpoint_path,
    read_checkpoint,
    restore_checkpoint,
    save_checkpoint,
)
from nerfkit.training.step import init_state, make_optimizer

SRC = Path(__file__).resolve().parents[2] / "src" / "nerfkit"
FIELD = dataclasses.asdict(preset("tiny").field)


def _sources():
    files = sorted(SRC.rglob("*.py"))
    assert len(files) > 10, SRC
    return files


PICKLE_MODULES = {"pickle", "cPickle", "_pickle", "dill", "cloudpickle", "joblib", "shelve"}


def _pickle_imports(tree) -> list[int]:
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            names = {(node.module or "").split(".")[0]}
        else:
            continue
        if names & PICKLE_MODULES:
            bad.append(node.lineno)
    return bad


def _unsafe_numpy_loads(tree) -> list[int]:
    """Lines calling np.load / numpy.load without a literal allow_pickle=False."""
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "load" \
                and isinstance(node.func.value, ast.Name) and node.func.value.id in ("np", "numpy"):
            kw = {k.arg: k.value for k in node.keywords}
            v = kw.get("allow_pickle")
            if not (isinstance(v, ast.Constant) and v.value is False):
                bad.append(node.lineno)
    return bad


def test_the_scanners_see_what_they_look_for():
    assert _pickle_imports(ast.parse("import os\nimport pickle\nfrom dill import loads")) == [2, 3]
    assert _unsafe_numpy_loads(ast.parse("a = np.load(p)\nb = np.load(p, allow_pickle=False)\n"
                                         "c = numpy.load(p, allow_pickle=True)")) == [1, 3]


def test_no_pickle_in_the_source():
    for path in _sources():
        assert _pickle_imports(ast.parse(path.read_text(), str(path))) == [], f"{path} imports a pickle module"


def test_every_numpy_load_refuses_pickles():
    for path in _sources():
        assert _unsafe_numpy_loads(ast.parse(path.read_text(), str(path))) == [], \
            f"{path}: np.load without allow_pickle=False"


class _Exploit:
    """Unpickling this creates a marker file: proof that a loader ran a pickle."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def _tiny_state(n_importance: int = 0):
    cfg = preset("tiny")
    cfg.sampler.n_importance = n_importance
    model = NeRFModel(cfg)
    opt, _ = make_optimizer(cfg)
    return jax.tree_util.tree_map(np.asarray, init_state(model, opt, 0))


def test_a_pickle_is_refused_and_never_run(tmp_path):
    marker = tmp_path / "pwned"
    path = checkpoint_path(tmp_path, 1)
    for protocol in (2, pickle.HIGHEST_PROTOCOL):
        path.write_bytes(pickle.dumps({"format": "nerfkit-checkpoint-v1", "x": _Exploit(marker)}, protocol=protocol))
        with pytest.raises(CheckpointError, match=r"ckpt_00000001\.msgpack: looks like a Python pickle"):
            restore_checkpoint(path, _tiny_state(), FIELD)
    path.write_bytes(pickle.dumps(_Exploit(marker), protocol=0))  # protocol 0 has no header: still never run
    with pytest.raises(CheckpointError, match=r"ckpt_00000001\.msgpack"):
        restore_checkpoint(path, _tiny_state(), FIELD)
    assert not marker.exists()


@pytest.mark.parametrize("payload,match", [
    (msgpack.packb({"hello": [1, 2]}), r"not a nerfkit checkpoint"),
    (msgpack.packb([1, 2, 3]), r"not a nerfkit checkpoint"),
    (msgpack.packb({"format": "nerfkit-checkpoint-v1", "step": "x", "field": {}, "state": {}}), r"damaged"),
    (msgpack.packb({"format": "nerfkit-checkpoint-v1", "step": 3, "field": 7, "state": {}}), r"damaged"),
    (msgpack.packb({"format": "nerfkit-checkpoint-v1", "step": 3, "field": {}, "state": [1]}), r"damaged"),
    (msgpack.packb({"format": "nerfkit-checkpoint-v1", "step": 3, "field": {}}), r"damaged"),
    (b"PK\x03\x04" + os.urandom(200), r"corrupted or truncated"),  # e.g. a .npz / torch zip
])
def test_foreign_or_damaged_files(tmp_path, payload, match):
    path = checkpoint_path(tmp_path, 5)
    path.write_bytes(payload)
    with pytest.raises(CheckpointError, match=match) as e:
        restore_checkpoint(path, _tiny_state(), FIELD)
    assert "ckpt_00000005.msgpack" in str(e.value) and "\n" not in str(e.value)


def test_corrupted_latest_points_to_the_previous_good_one(tmp_path):
    state = _tiny_state()
    save_checkpoint(tmp_path, 10, state, FIELD, keep=3)
    newest = save_checkpoint(tmp_path, 20, state, FIELD, keep=3)
    newest.write_bytes(newest.read_bytes()[:-100])
    with pytest.raises(CheckpointError, match=r"ckpt_00000020\.msgpack: corrupted or truncated checkpoint .*"
                                              r"move it away to fall back to ckpt_00000010\.msgpack"):
        restore_checkpoint(newest, state, FIELD)


def test_checkpoint_of_another_model_says_what_differs(tmp_path):
    hier = _tiny_state(n_importance=8)  # a fine network too (--n-importance 8), same field config
    path = save_checkpoint(tmp_path, 3, hier, FIELD, keep=3)
    with pytest.raises(CheckpointError, match=r"params/fine: in the checkpoint, not in this model.*--n-importance"):
        restore_checkpoint(path, _tiny_state(), FIELD)
    with pytest.raises(CheckpointError, match=r"params/fine: in this model, not in the checkpoint"):
        restore_checkpoint(save_checkpoint(tmp_path, 4, _tiny_state(), FIELD, keep=3), hier, FIELD)
    # Same names, other shape or dtype: the path and both shapes are named.
    state = _tiny_state()
    other = jax.tree_util.tree_map(np.copy, state)
    other["params"]["coarse"]["sigma"]["w"] = np.zeros((32, 2), np.float32)
    other["params"]["coarse"]["sigma"]["b"] = np.zeros(1, np.float64)
    path = save_checkpoint(tmp_path, 5, other, FIELD, keep=3)
    with pytest.raises(CheckpointError) as e:
        restore_checkpoint(path, state, FIELD)
    msg = str(e.value)
    assert "params/coarse/sigma/w: shape/dtype checkpoint float32[32, 2] vs model float32[32, 1]" in msg
    assert "params/coarse/sigma/b: shape/dtype checkpoint float64[1] vs model float32[1]" in msg
    assert "\n" not in msg
    # A different field config is named key by key (before any array is looked at).
    with pytest.raises(CheckpointError, match=r"width: checkpoint 32 vs config 64"):
        restore_checkpoint(path, state, {**FIELD, "width": 64})


def test_round_trip_still_exact(tmp_path):
    state = _tiny_state(n_importance=8)
    step, back = restore_checkpoint(save_checkpoint(tmp_path, 9, state, FIELD, keep=1), state, FIELD)
    assert step == 9
    for a, b in zip(jax.tree_util.tree_leaves(state), jax.tree_util.tree_leaves(back)):
        assert np.asarray(a).dtype == np.asarray(b).dtype
        np.testing.assert_array_equal(a, b)
    assert read_checkpoint(checkpoint_path(tmp_path, 9))["field"] == FIELD
