"""glibc's malloc tunables for the suite's test processes (conftest.py sets them before pytest-xdist starts them):
transparent huge pages for malloc's large blocks (`glibc.malloc.hugetlb=1`, glibc >= 2.35).

XLA:CPU keeps a training step's buffers in malloc'd blocks, and glibc serves a block above its mmap threshold (at
most 32 MiB, whatever `MALLOC_MMAP_THRESHOLD_` asks) with a fresh mmap that faults in one 4 KiB page at a time, each
time the block is allocated. With the tunable, glibc asks the kernel for 2 MiB pages there (madvise), where the
kernel allows them (/sys/kernel/mm/transparent_hugepage/enabled: `always` or `madvise`). Measured on 2 cores,
tests/models/test_unbounded.py's ring test alone (one process): 9.4 M minor page faults -> 0.4 M, system time 23-26 s
-> 11 s, user time within noise.

glibc reads $GLIBC_TUNABLES once, when a process starts: the tunable reaches the test processes pytest-xdist starts
after conftest.py ran, and their subprocesses (the CLI tests), not the process that ran it. A glibc that does not know
a tunable ignores it.
"""

from __future__ import annotations

import os
import platform

TUNABLE = "glibc.malloc.hugetlb"
FIRST_GLIBC = (2, 35)  # the first glibc that knows TUNABLE


def _glibc() -> tuple[int, ...] | None:
    """(major, minor) of this process's glibc, or None where it runs on another C library."""
    name, version = platform.libc_ver()
    if name != "glibc" or not version:
        return None
    return tuple(int(x) for x in version.split(".")[:2])


def suite_tunables(environ: dict | None = None) -> str | None:
    """Add TUNABLE=1 to environ["GLIBC_TUNABLES"] (os.environ by default) where it does not name TUNABLE already and
    this process's C library is a glibc that knows it; returns what was added, or None."""
    env = os.environ if environ is None else environ
    version = _glibc()
    current = env.get("GLIBC_TUNABLES", "")
    if version is None or version < FIRST_GLIBC or TUNABLE in current:
        return None
    added = f"{TUNABLE}=1"
    env["GLIBC_TUNABLES"] = f"{current}:{added}" if current else added
    return added
