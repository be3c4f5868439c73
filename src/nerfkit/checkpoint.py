"""Checkpoints: msgpack files written atomically (no pickle anywhere).

A checkpoint holds {"format", "step", "field", "state"}: the step, the field config it was
made with (so a mismatch can be explained), and the training state (params, optimizer
state, non-trainable model state) as a msgpack tree of arrays.

Writes go to a temporary file in the same folder, are flushed and fsync'ed, then
renamed over the final name: a reader sees the old file or the new one, never half of
one. Older checkpoints are deleted only after the new one is in place.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import jax
import numpy as np
from flax import serialization

from nerfkit.errors import CheckpointError

FORMAT = "nerfkit-checkpoint-v1"
_NAME = re.compile(r"^ckpt_(\d{8})\.msgpack$")


def checkpoint_path(ckpt_dir: Path, step: int) -> Path:
    return ckpt_dir / f"ckpt_{step:08d}.msgpack"


def list_checkpoints(ckpt_dir: Path) -> list[Path]:
    """Complete checkpoints in ckpt_dir, oldest first (temporary files are ignored)."""
    if not ckpt_dir.is_dir():
        return []
    found = [(int(m.group(1)), p) for p in ckpt_dir.iterdir() if (m := _NAME.match(p.name))]
    return [p for _, p in sorted(found)]


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    try:  # make the rename itself durable
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def save_checkpoint(ckpt_dir: Path, step: int, state, field_cfg: dict, keep: int) -> Path:
    """Write state at `step`, then delete all but the newest `keep` checkpoints."""
    host_state = jax.tree_util.tree_map(np.asarray, serialization.to_state_dict(state))
    blob = serialization.msgpack_serialize({"format": FORMAT, "step": int(step), "field": field_cfg, "state": host_state})
    path = checkpoint_path(ckpt_dir, step)
    atomic_write_bytes(path, blob)
    for old in list_checkpoints(ckpt_dir)[:-keep]:
        old.unlink(missing_ok=True)
    return path


def read_checkpoint(path: Path) -> dict:
    """The raw checkpoint dict; CheckpointError if the file is not a complete nerfkit checkpoint."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise CheckpointError(f"{path}: cannot read checkpoint ({e.strerror})") from None
    try:
        ckpt = serialization.msgpack_restore(data)
    except Exception as e:  # msgpack raises several unrelated types on garbage
        raise CheckpointError(f"{path}: corrupted or truncated checkpoint ({type(e).__name__})") from None
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise CheckpointError(f"{path}: not a nerfkit checkpoint")
    return ckpt


def restore_checkpoint(path: Path, target, field_cfg: dict):
    """Restore into the structure of `target`; returns (step, state).

    Refuses, naming the differences, a checkpoint made with another field config.
    """
    ckpt = read_checkpoint(path)
    saved = ckpt.get("field", {})
    diff = [f"{k}: checkpoint {saved.get(k)!r} vs config {field_cfg.get(k)!r}"
            for k in sorted(set(saved) | set(field_cfg)) if saved.get(k) != field_cfg.get(k)]
    if diff:
        raise CheckpointError(f"{path}: made with a different field config ({'; '.join(diff)})")
    try:
        state = serialization.from_state_dict(target, ckpt["state"])
    except (ValueError, KeyError, TypeError) as e:
        raise CheckpointError(f"{path}: checkpoint does not match this model ({e})") from None
    bad = [
        jax.tree_util.keystr(kp)
        for (kp, a), b in zip(jax.tree_util.tree_leaves_with_path(state), jax.tree_util.tree_leaves(target))
        if np.shape(a) != np.shape(b)
    ]
    if bad:
        raise CheckpointError(f"{path}: array shapes differ from this model at {', '.join(bad[:3])}")
    return int(ckpt["step"]), state


def latest_checkpoint(ckpt_dir: Path) -> Path | None:
    found = list_checkpoints(ckpt_dir)
    return found[-1] if found else None
