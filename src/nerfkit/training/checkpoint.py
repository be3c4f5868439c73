"""Checkpoints: msgpack files written atomically (no pickle anywhere).

A checkpoint holds {"format", "step", "field", "state"}: the step, the field config it was
made with (so a mismatch can be explained), and the training state (params, optimizer
state, non-trainable model state) as a msgpack tree of arrays.

Writes go to a temporary file in the same folder, are flushed and fsync'ed, then
renamed over the final name: a reader sees the old file or the new one, never half of
one. Older checkpoints are deleted only after the new one is in place.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import jax
import numpy as np
from flax import serialization

from nerfkit.core.config import FIELD_BEFORE, FieldConfig
from nerfkit.core.errors import CheckpointError
from nerfkit.core.outputs import replace_with

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


_TMP = re.compile(r"^\.ckpt_\d{8}\.msgpack\.tmp-(\d+)$")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. another user's process
        return True
    return True


def _remove_stale_temporaries(ckpt_dir: Path) -> None:
    """Delete temporaries left by writers killed mid-write (their process is gone)."""
    for p in ckpt_dir.iterdir():
        m = _TMP.match(p.name)
        if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
            p.unlink(missing_ok=True)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` so that a reader (or a crash) sees the old file or the new one, never a mix."""
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())

    replace_with(path, write)
    try:  # make the rename itself durable
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def save_checkpoint(ckpt_dir: Path, step: int, state, field_cfg: dict, keep: int) -> Path:
    """Write state at `step`, then delete all but the newest `keep` checkpoints (and, before writing, any beyond
    `keep` that a writer killed between its rename and its pruning left: so there are never more than keep + 1)."""
    host_state = jax.tree_util.tree_map(np.asarray, serialization.to_state_dict(state))
    blob = serialization.msgpack_serialize({"format": FORMAT, "step": int(step), "field": field_cfg, "state": host_state})
    path = checkpoint_path(Path(ckpt_dir), step)
    _prune(Path(ckpt_dir), keep)
    atomic_write_bytes(path, blob)
    _prune(Path(ckpt_dir), keep)  # only now that the new checkpoint is complete and renamed into place
    _remove_stale_temporaries(Path(ckpt_dir))
    return path


def _prune(ckpt_dir: Path, keep: int) -> None:
    """Delete all but the newest `keep` complete checkpoints in ckpt_dir."""
    for old in list_checkpoints(ckpt_dir)[:-keep]:
        old.unlink(missing_ok=True)


def _fallback_hint(path: Path) -> str:
    older = [p for p in list_checkpoints(Path(path).parent) if p != Path(path)]
    if not older:
        return ""
    return f"; move it away to fall back to {older[-1].name}"


def read_checkpoint(path: Path) -> dict:
    """The raw checkpoint dict; CheckpointError if the file is not a complete nerfkit checkpoint.

    Only msgpack is parsed (arrays come back through numpy's frombuffer): nothing in a
    checkpoint can run code.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise CheckpointError(f"{path}: cannot read checkpoint ({e.strerror or e})") from None
    if data[:1] == b"\x80" and data[-1:] == b".":  # pickle protocol 2+ header and STOP opcode
        raise CheckpointError(f"{path}: looks like a Python pickle, not a nerfkit checkpoint "
                              f"(nerfkit never unpickles files)")
    try:
        ckpt = serialization.msgpack_restore(data)
    except Exception as e:  # noqa: BLE001 - msgpack raises several unrelated types on garbage
        raise CheckpointError(f"{path}: corrupted or truncated checkpoint ({type(e).__name__})"
                              f"{_fallback_hint(path)}") from None
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise CheckpointError(f"{path}: not a nerfkit checkpoint (no {FORMAT!r} header){_fallback_hint(path)}")
    step, field, state = ckpt.get("step"), ckpt.get("field"), ckpt.get("state")
    if not isinstance(step, int) or isinstance(step, bool) or step < 0 or not isinstance(field, dict) \
            or not isinstance(state, dict):
        raise CheckpointError(f"{path}: damaged nerfkit checkpoint (bad step, field or state entry)"
                              f"{_fallback_hint(path)}")
    return ckpt


def _describe(a) -> str:
    return f"{np.asarray(a).dtype.name}{list(np.shape(a))}"


def _structure_diff(saved, model, path: str = "", top: bool = True) -> list[str]:
    """What differs between the checkpoint's state dict and the model's, by path.

    A subtree present on one side only is named once ("params/fine: in the checkpoint,
    not in this model"). Top-level entries the model does not ask for (e.g. "elapsed")
    are ignored.
    """
    if isinstance(model, dict):
        if not isinstance(saved, dict):
            return [f"{path}: checkpoint holds {type(saved).__name__}, the model a group of arrays"]
        diff = []
        if not top:
            diff += [f"{path}/{k}: in the checkpoint, not in this model" for k in sorted(set(saved) - set(model), key=str)]
        diff += [f"{path + '/' if path else ''}{k}: in this model, not in the checkpoint"
                 for k in sorted(set(model) - set(saved), key=str)]
        for k in sorted(set(saved) & set(model), key=str):
            diff += _structure_diff(saved[k], model[k], f"{path}/{k}" if path else str(k), top=False)
        return diff
    if not isinstance(saved, (np.ndarray, np.generic, int, float, bool)):
        return [f"{path}: checkpoint holds {type(saved).__name__}, not an array"]
    if np.shape(saved) != np.shape(model) or np.asarray(saved).dtype != np.asarray(model).dtype:
        return [f"{path}: shape/dtype checkpoint {_describe(saved)} vs model {_describe(model)}"]
    return []


def restore_checkpoint(path: Path, target, field_cfg: dict):
    """Restore into the structure of `target`; returns (step, state).

    Refuses, naming the differences, a checkpoint made with another field config or whose
    arrays (names, shapes, dtypes) differ from the model's.
    """
    ckpt = read_checkpoint(path)
    # Knobs added to FieldConfig after a checkpoint was written take their defaults, or what such runs trained with.
    saved = {**dataclasses.asdict(FieldConfig()), **FIELD_BEFORE, **ckpt["field"]}
    diff = [f"{k}: checkpoint {saved.get(k)!r} vs config {field_cfg.get(k)!r}"
            for k in sorted(set(saved) | set(field_cfg)) if saved.get(k) != field_cfg.get(k)]
    if diff:
        raise CheckpointError(f"{path}: made with a different field config ({'; '.join(diff)})")
    target_sd = jax.tree_util.tree_map(np.asarray, serialization.to_state_dict(target))
    diff = _structure_diff(ckpt["state"], target_sd)
    if diff:
        more = f" and {len(diff) - 4} more" if len(diff) > 4 else ""
        raise CheckpointError(f"{path}: checkpoint does not match this model (array shapes or names differ: "
                              f"{'; '.join(diff[:4])}{more}); was it made with another config "
                              f"(e.g. --n-importance, --kind)?")
    try:
        state = serialization.from_state_dict(target, ckpt["state"])
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise CheckpointError(f"{path}: checkpoint does not match this model ({e})") from None
    return int(ckpt["step"]), state


def latest_checkpoint(ckpt_dir: Path) -> Path | None:
    found = list_checkpoints(ckpt_dir)
    return found[-1] if found else None


def checkpoint_step(path: Path) -> int:
    """The step a checkpoint file holds, from its name (checkpoint_path)."""
    return int(_NAME.match(Path(path).name).group(1))
