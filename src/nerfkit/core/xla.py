"""XLA compiler options nerfkit sets for itself, before JAX starts its backends.

XLA:CPU's newer fusion emitters (the default since jaxlib 0.5.3) compile nerfkit's programs 20-40% slower
than the classic ones and run them no faster: measured on 2 cores with jaxlib 0.10.2, the ngp training
step of tests/models/test_unbounded.py compiles in 5.3 s instead of 8.5 s, the lego ngp and splat steps
run at the same rate (splat: steps 50 to 300 in 17.8 s vs 20.2 s), and eval renders the same pixels (PSNR equal to
the last digit). So `--xla_cpu_use_fusion_emitters=false` is added to $XLA_FLAGS, unless $XLA_FLAGS
already names that flag (the user's choice wins) or jaxlib is older than the flag (an unknown flag in
$XLA_FLAGS aborts the process). It only touches XLA:CPU; GPU compilation is unchanged.
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


def default_flags(environ: dict | None = None) -> str | None:
    """Add nerfkit's XLA flags to environ["XLA_FLAGS"] (os.environ by default) where the user has not set
    them and the installed jaxlib knows them; returns the flag added, or None. Has an effect only before
    JAX creates its CPU backend (the first computation)."""
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
