"""Test-session set-up: one persistent JAX compilation cache for the whole session (in a temporary
folder, not the user's ~/.cache), so functions that several tests compile alike compile once."""

import os
import tempfile

import pytest


@pytest.fixture(scope="session", autouse=True)
def compile_cache():
    with tempfile.TemporaryDirectory(prefix="nerfkit-jax-cache-") as path:
        old = os.environ.get("NERFKIT_COMPILE_CACHE")
        os.environ["NERFKIT_COMPILE_CACHE"] = path
        from nerfkit.cli import enable_compile_cache

        enable_compile_cache()
        yield path
        if old is None:
            os.environ.pop("NERFKIT_COMPILE_CACHE", None)
        else:
            os.environ["NERFKIT_COMPILE_CACHE"] = old
