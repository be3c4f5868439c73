"""Item 2: a process killed with SIGKILL while saving leaves a loadable latest checkpoint.

A helper process imports nerfkit once and, on request, forks a "saver" that writes
checkpoints of a ~4 MB state in a tight loop (nerfkit.training.checkpoint.save_checkpoint, keep=2).
The test SIGKILLs the saver at random moments; after every kill the newest complete
checkpoint must restore cleanly and hold exactly the state of its step. Kills are repeated
until several of them landed in the middle of a write (a temporary file was left behind),
so the test really exercises the dangerous window: with a plain, non-atomic
`open(path, "wb").write(...)` it fails within a few kills.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np

from nerfkit.core.config import FieldConfig
from nerfkit.training.checkpoint import (
    latest_checkpoint,
    list_checkpoints,
    restore_checkpoint,
    save_checkpoint,
)

FIELD = dataclasses.asdict(FieldConfig(width=8))
SIDE = 1024  # a 1024 x 1024 float32 leaf: 4 MB per checkpoint

SPAWNER = textwrap.dedent(
    """
    import dataclasses, os, sys
    from pathlib import Path
    import numpy as np
    from nerfkit.training.checkpoint import latest_checkpoint, save_checkpoint
    from nerfkit.core.config import FieldConfig

    ckpt_dir, side = Path(sys.argv[1]), int(sys.argv[2])
    field = dataclasses.asdict(FieldConfig(width=8))

    def state_for(step):
        w = np.full((side, side), step, np.float32)
        w[0, :8] = np.arange(8) + step  # not one constant: any torn or mixed write shows
        return {"params": {"w": w, "b": np.arange(5, dtype=np.float32) * step}, "count": np.int32(step)}

    for line in sys.stdin:
        pid = os.fork()
        if pid == 0:  # the saver: continue after the newest checkpoint, forever
            step = int(latest_checkpoint(ckpt_dir).name[5:13]) + 1
            while True:
                save_checkpoint(ckpt_dir, step, state_for(step), field, keep=2)
                step += 1
        print(pid, flush=True)
        os.waitpid(pid, 0)
        print("reaped", flush=True)
    """
)


def state_for(step: int) -> dict:
    w = np.full((SIDE, SIDE), step, np.float32)
    w[0, :8] = np.arange(8) + step
    return {"params": {"w": w, "b": np.arange(5, dtype=np.float32) * step}, "count": np.int32(step)}


def test_sigkill_during_saves_leaves_a_loadable_latest_checkpoint(tmp_path):
    ckpt_dir = tmp_path / "checkpoints"
    save_checkpoint(ckpt_dir, 0, state_for(0), FIELD, keep=2)
    template = {"params": {"w": np.zeros((SIDE, SIDE), np.float32), "b": np.zeros(5, np.float32)},
                "count": np.int32(0)}
    script = tmp_path / "spawner.py"
    script.write_text(SPAWNER)
    spawner = subprocess.Popen([sys.executable, str(script), str(ckpt_dir), str(SIDE)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
    rng = np.random.default_rng(0)
    kills = mid_write = 0
    last_step = 0
    try:
        while kills < 40 and (mid_write < 3 or kills < 8):
            spawner.stdin.write("go\n")
            spawner.stdin.flush()
            pid = int(spawner.stdout.readline())
            time.sleep(rng.uniform(0.02, 0.12))
            os.kill(pid, signal.SIGKILL)
            assert spawner.stdout.readline().strip() == "reaped"
            kills += 1
            leftovers = [p for p in ckpt_dir.iterdir() if ".tmp-" in p.name]
            mid_write += bool(leftovers)
            # The newest complete checkpoint restores, and holds exactly its step's state.
            latest = latest_checkpoint(ckpt_dir)
            step, state = restore_checkpoint(latest, template, FIELD)
            assert step >= last_step
            last_step = step
            expect = state_for(step)
            np.testing.assert_array_equal(state["params"]["w"], expect["params"]["w"])
            np.testing.assert_array_equal(state["params"]["b"], expect["params"]["b"])
            assert int(state["count"]) == step
            # keep=2: older checkpoints are pruned only after a newer one is complete (a kill between the
            # rename and the pruning leaves one extra, which the next save removes before it writes, so kills in
            # that window one after the other leave no more); all of them load.
            assert 1 <= len(list_checkpoints(ckpt_dir)) <= 3
            for older in list_checkpoints(ckpt_dir):
                restore_checkpoint(older, template, FIELD)
    finally:
        spawner.stdin.close()
        spawner.wait(timeout=30)
    assert last_step > 0, "the saver never completed a checkpoint"
    # The kills did hit the dangerous window, not only the gaps between writes.
    assert mid_write >= 1, f"none of {kills} kills landed inside a write"
    # A later save cleans up the temporaries of killed writers.
    save_checkpoint(ckpt_dir, last_step + 1000, state_for(0), FIELD, keep=2)
    assert not [p for p in ckpt_dir.iterdir() if ".tmp-" in p.name]
    assert len(list_checkpoints(ckpt_dir)) == 2
