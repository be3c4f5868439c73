"""Each test process on a core of its own (conftest.py calls pin_worker as it starts)."""

from __future__ import annotations

import os
import re


def pin_worker(worker: str | None) -> set[int] | None:
    """Pin a pytest-xdist test process (worker "gwK") to one CPU of those it may use, the K-th (mod their count),
    before JAX starts its backend; returns the CPUs it now has, or None where it changes nothing (no worker, one
    CPU, or an OS without affinity masks). With one test process per core (`-n auto`), each process's XLA thread
    pool and the CPU kernels' worker threads (nerfkit/core/threads.py) then size themselves to one core instead
    of every process taking all of them: a subset of six long files on 2 cores, A B B A in one sitting, took 211
    / 221 s of wall time and 376 / 396 s of CPU unpinned against 195 / 201 s and 346 / 357 s pinned (CHANGELOG.md,
    "The suite"). The processes nerfkit's verbs start in a test inherit the pin."""
    if not worker or not hasattr(os, "sched_setaffinity"):
        return None
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        return None
    k = int(re.sub(r"\D", "", worker) or 0) % len(cpus)
    os.sched_setaffinity(0, {cpus[k]})
    return {cpus[k]}
