"""Test-session set-up: one persistent JAX compilation cache for the whole session (in a temporary
folder, not the user's ~/.cache), so functions that several tests compile alike compile once."""

import os
import tempfile

import pytest
from chromium import CHROMIUM_NAMES, find_chromium


@pytest.fixture(scope="session", autouse=True)
def compile_cache():
    with tempfile.TemporaryDirectory(prefix="nerfkit-jax-cache-") as path:
        old = os.environ.get("NERFKIT_COMPILE_CACHE")
        os.environ["NERFKIT_COMPILE_CACHE"] = path
        from nerfkit.cli.main import enable_compile_cache

        enable_compile_cache()
        yield path
        if old is None:
            os.environ.pop("NERFKIT_COMPILE_CACHE", None)
        else:
            os.environ["NERFKIT_COMPILE_CACHE"] = old


@pytest.fixture(scope="session")
def procedural_run(tmp_path_factory):
    """(run, moved copy, training poses) of the shared procedural-scene run (procedural_run.py)."""
    from procedural_run import train_scene

    return train_scene(tmp_path_factory.mktemp("procedural_run"))


@pytest.fixture
def chromium():
    """The headless Chromium binary for the real-browser tests (skips, saying how to install it, when absent)."""
    binary = find_chromium()
    if binary is None:
        pytest.skip("no Chromium found (looked for " + ", ".join(CHROMIUM_NAMES) + " and $NERFKIT_CHROMIUM); "
                    "install the Debian package: apt-get install chromium (.ci/run does this)")
    return binary
