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
"""

from __future__ import annotations

import os
import re
from importlib import metadata

FLAG = "xla_cpu_use_fusion_emitters"
FIRST_JAXLIB = (0, 5, 3)  # the first jaxlib whose XLA knows FLAG (0.5.0 does not)


def _version(text: str) -> tuple[int, ...]:
    """(major, minor, patch) of a version string such as '0.10.2' or '0.5.3.dev20250101'."""
    return tuple(int(x) for x in re.findall(r"\d+", text)[:3])


def suite_flags(environ: dict | None = None) -> str | None:
    """Add the suite's XLA flags to environ["XLA_FLAGS"] (os.environ by default) where they are not set and the
    installed jaxlib knows them; returns the flag added, or None. Has an effect only before JAX creates its CPU
    backend (the first computation)."""
    env = os.environ if environ is None else environ
    flags = env.get("XLA_FLAGS", "")
    if FLAG in flags:
        return None
    try:
        if _version(metadata.version("jaxlib")) < FIRST_JAXLIB:
            return None
    except metadata.PackageNotFoundError:
        return None
    added = f"--{FLAG}=false"
    env["XLA_FLAGS"] = f"{flags} {added}".strip()
    return added
