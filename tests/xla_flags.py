"""The XLA compiler options the test suite runs under (conftest.py sets them before JAX starts its backends; the
test processes' subprocesses inherit them).

XLA:CPU's newer fusion emitters (the default since jaxlib 0.5.3) compile nerfkit's programs 20-40% slower than
the classic ones: measured on 2 cores with jaxlib 0.10.2, the ngp training step of tests/models/test_unbounded.py
compiles in 5.3 s instead of 8.5 s, and the suite's summed compile time falls from 678 to 450 s. The suite is
mostly compilation, so it asks for the classic ones (`--xla_cpu_use_fusion_emitters=false`), unless $XLA_FLAGS
already names that flag or jaxlib is older than the flag (an unknown flag in $XLA_FLAGS aborts the process).
nerfkit itself leaves XLA's default: the classic emitters run the MLP presets' steps 10-20% slower (seed preset,
1024 rays x 64 samples: 598 and 656 ms against 540 and 537 ms, `benchmarks/vanilla_step.py`, one sitting),
which outweighs their 3-4 s faster start of an ngp or splat run (docs/measurements.md).

It also asks LLVM for its optimisation level 1 instead of 2 (`--xla_backend_optimization_level=1`): with XLA's
default emitters the ngp step above compiled in 8.6 / 8.1 s against 10.5 / 9.5 s, its 200-step run 28.3 s against
30.1, and under this suite's flags four compile-heavy files (test_unbounded, test_ngp, test_ngp_proposal,
test_flags; -n 2, A B A B in one sitting) took 451 / 454 s of CPU against 487 / 503 (CHANGELOG.md, "The suite").
nerfkit itself keeps XLA's default level.
"""

from __future__ import annotations

import os
import re
from importlib import metadata

FLAG = "xla_cpu_use_fusion_emitters"
FLAGS = {FLAG: "false", "xla_backend_optimization_level": "1"}  # each added unless $XLA_FLAGS names it
FIRST_JAXLIB = (0, 5, 3)  # the first jaxlib whose XLA knows FLAG (0.5.0 does not)


def _version(text: str) -> tuple[int, ...]:
    """(major, minor, patch) of a version string such as '0.10.2' or '0.5.3.dev20250101'."""
    return tuple(int(x) for x in re.findall(r"\d+", text)[:3])


def suite_flags(environ: dict | None = None) -> str | None:
    """Add the suite's XLA flags (FLAGS) to environ["XLA_FLAGS"] (os.environ by default), each where it is not set
    and the installed jaxlib knows FLAG; returns the flags added, or None. Has an effect only before JAX creates
    its CPU backend (the first computation)."""
    env = os.environ if environ is None else environ
    flags = env.get("XLA_FLAGS", "")
    try:
        if _version(metadata.version("jaxlib")) < FIRST_JAXLIB:
            return None
    except metadata.PackageNotFoundError:
        return None
    added = " ".join(f"--{name}={value}" for name, value in FLAGS.items() if name not in flags)
    if not added:
        return None
    env["XLA_FLAGS"] = f"{flags} {added}".strip()
    return added
