"""What a benchmark result was measured on: the commit, a clean or dirty tree, the date, the machine and
the command. Every benchmark script puts this into the JSON it writes, so a figure quoted from that JSON
says which code produced it."""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Read when a benchmark imports this module (its start), not when it writes its record (the end, for most).
LOAD_AT_START = round(os.getloadavg()[0], 2)


def _git(*args: str) -> str:
    try:
        r = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, timeout=10)
        return r.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def provenance() -> dict:
    """{commit, dirty (None: unknown), diff_sha256, date, command, python, cpus, machine, load_at_start}:
    diff_sha256 is the SHA-256 of `git diff HEAD` (the uncommitted changes to tracked files) when dirty, so a
    record measured on a dirty tree names the exact code; load_at_start is the 1-minute load average when the
    benchmark started (the machine is shared, so a figure measured under load says so)."""
    # A copy of the tree on a lent GPU machine: the commit comes from NERFKIT_COMMIT, set by whoever copied it,
    # and dirty is unknown (that copy may carry a .git of an older commit: 2026-12-04's did, so its records named
    # the session's first commit, not the code they ran). The records themselves (benchmarks/results) do not
    # count: a benchmark's own output must not make the next one's tree dirty.
    given = os.environ.get("NERFKIT_COMMIT", "")
    commit = given or _git("rev-parse", "HEAD")
    code = (".", ":(exclude)benchmarks/results")
    dirty = bool(_git("status", "--porcelain", "--untracked-files=no", "--", *code)) if commit and not given else None
    diff = hashlib.sha256(_git("diff", "HEAD", "--", *code).encode()).hexdigest() if dirty else None
    return {"commit": commit, "dirty": dirty, "diff_sha256": diff,
            "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
            "python": platform.python_version(), "cpus": os.cpu_count(), "machine": platform.machine(),
            "load_at_start": LOAD_AT_START}
