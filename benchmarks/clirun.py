"""The command line as a user runs it, from a benchmark: one `python -m nerfkit ...` process, timed whole."""

from __future__ import annotations

import contextlib
import shlex
import subprocess
import sys
import time
from pathlib import Path


def nerfkit(*args, stderr: Path | None = None, env: dict | None = None) -> tuple[float, str]:
    """Run `nerfkit ARGS` in its own process (as a user would; each argument as str()): (wall seconds, stdout).
    Its stderr (progress bars) goes to the file `stderr`, else to this process's; env: its environment (default:
    this process's). A failed command ends the benchmark with one line naming it."""
    args = [str(x) for x in args]
    t0 = time.perf_counter()
    with open(stderr, "w") if stderr else contextlib.nullcontext() as err:
        r = subprocess.run([sys.executable, "-m", "nerfkit", *args], stdout=subprocess.PIPE, stderr=err, env=env,
                           text=True, check=False)
    if r.returncode != 0:
        raise SystemExit(f"nerfkit {shlex.join(args)} failed (exit {r.returncode})")
    return time.perf_counter() - t0, r.stdout
