"""Each test process on a share of the cores of its own (conftest.py calls pin_worker as it starts)."""

from __future__ import annotations

import os
import re


def cpu_share(cpus: list[int], k: int, count: int) -> list[int]:
    """The CPUs of test process k of count: cpus split into count runs as even as they come (run k is cpus[k n /
    count : (k + 1) n / count] for n CPUs), or the single CPU k mod n where there are more processes than CPUs."""
    n = len(cpus)
    if count >= n:
        return [cpus[k % n]]
    return cpus[k * n // count: (k + 1) * n // count]


def pin_worker(worker: str | None, count: str | None) -> set[int] | None:
    """Pin a pytest-xdist test process (worker "gwK" of `count`) to its cpu_share of the CPUs it may use, before JAX
    starts its backend; returns the CPUs it now has, or None where it changes nothing (no worker, one process or
    one CPU, an OS without affinity masks). With one test process per core (`-n auto` on up to MAX_WORKERS cores),
    each process's XLA thread pool and the CPU kernels' worker threads (nerfkit/core/threads.py) then size
    themselves to its own core instead of every process taking all of them: a subset of six long files on 2 cores,
    A B B A in one sitting, took 211 / 221 s of wall time and 376 / 396 s of CPU unpinned against 195 / 201 s and
    346 / 357 s pinned (CHANGELOG.md, "The suite"). The processes nerfkit's verbs start in a test inherit the pin."""
    if not worker or not hasattr(os, "sched_setaffinity"):
        return None
    cpus = sorted(os.sched_getaffinity(0))
    workers = int(count or 1)
    if len(cpus) < 2 or workers < 2:
        return None
    mine = set(cpu_share(cpus, int(re.sub(r"\D", "", worker) or 0), workers))
    os.sched_setaffinity(0, mine)
    return mine
