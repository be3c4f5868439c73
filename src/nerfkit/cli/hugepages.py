"""Transparent huge pages for malloc's large blocks, for the verbs that run XLA: `nerfkit` starts itself again
once with glibc's `glibc.malloc.hugetlb=1` tunable.

XLA:CPU holds a step's buffers in malloc'd blocks, and glibc serves a block above its mmap threshold (at most
32 MiB, whatever `MALLOC_MMAP_THRESHOLD_` asks) with a fresh mmap whose pages the kernel faults in 4 KiB at a time,
every time the block is allocated: an ngp training step on lego at 200 px faults in about 60,000 pages. With the
tunable (glibc >= 2.35) glibc asks the kernel for 2 MiB pages there (madvise), which it gives where transparent huge
pages are `always` or `madvise` (/sys/kernel/mm/transparent_hugepage/enabled). Measured with
benchmarks/malloc_hugepages.py (benchmarks/results/malloc_hugepages.json).

glibc reads $GLIBC_TUNABLES only when a process starts, so the command line replaces its process (os.execve: the
same process id, arguments and standard streams) with the tunable added, before it imports JAX. Nothing happens
where $NERFKIT_HUGEPAGES is `off`, $GLIBC_TUNABLES already names the tunable, or the C library or the kernel would
not use it; library callers of `nerfkit.cli.main.main(argv)` are never restarted.
"""

from __future__ import annotations

import os
import platform
import re
import sys
from pathlib import Path

from nerfkit.core.interrupts import block_across_exec, unblock

TUNABLE = "glibc.malloc.hugetlb"
FIRST_GLIBC = (2, 35)  # the first glibc that knows TUNABLE
THP = Path("/sys/kernel/mm/transparent_hugepage/enabled")


def glibc_version() -> tuple[int, ...] | None:
    """(major, minor) of this process's glibc, or None where it runs on another C library."""
    name, version = platform.libc_ver()
    numbers = re.findall(r"\d+", version)
    if name != "glibc" or len(numbers) < 2:
        return None
    return int(numbers[0]), int(numbers[1])


def thp_mode() -> str | None:
    """The kernel's transparent huge page mode (`always`, `madvise` or `never`), or None where it has none."""
    try:
        text = THP.read_text()
    except OSError:
        return None
    return text[text.index("[") + 1:text.index("]")] if "[" in text else None


def huge_page_environment(environ: dict, glibc: tuple[int, ...] | None, thp: str | None) -> dict | None:
    """The environment to start again with (environ with TUNABLE=1 added to GLIBC_TUNABLES), or None where
    nothing would change: $NERFKIT_HUGEPAGES off, the tunable already named, a C library that is not a glibc
    >= 2.35, or a kernel without transparent huge pages for madvise."""
    if environ.get("NERFKIT_HUGEPAGES", "").strip().lower() in ("0", "off", "no", "false"):
        return None
    current = environ.get("GLIBC_TUNABLES", "")
    if TUNABLE in current or glibc is None or glibc < FIRST_GLIBC or thp not in ("always", "madvise"):
        return None
    return {**environ, "GLIBC_TUNABLES": f"{current}:{TUNABLE}=1" if current else f"{TUNABLE}=1"}


def restart_with_huge_pages() -> None:
    """Replace this process with the same command under huge_page_environment, where it changes anything
    (returns otherwise, or where the restart itself fails)."""
    if not sys.platform.startswith("linux") or not sys.executable or not getattr(sys, "orig_argv", None):
        return
    env = huge_page_environment(dict(os.environ), glibc_version(), thp_mode())
    if env is None:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    block_across_exec(env)  # a Ctrl-C while the new process starts reaches its handlers (core/interrupts.py)
    try:
        os.execve(sys.executable, [sys.executable, *sys.orig_argv[1:]], env)
    except OSError:
        unblock()
        return
