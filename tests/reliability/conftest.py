"""Shared fixtures of the reliability tests: a persistent XLA compilation cache.

These tests start several short training runs of the same tiny model (subprocesses and
in-process); compiling the same train step again for each would dominate their run time
on a small CPU machine. A cache directory private to this test session lets every run
after the first load the compiled program instead. It changes how long compilation takes,
nothing else.
"""

from __future__ import annotations

import os

import jax
import pytest

_CACHE_OPTIONS = {
    "jax_compilation_cache_dir": "JAX_COMPILATION_CACHE_DIR",
    "jax_persistent_cache_min_compile_time_secs": "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS",
    "jax_persistent_cache_min_entry_size_bytes": "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES",
}


@pytest.fixture(scope="session")
def compile_cache_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("xla-cache")


@pytest.fixture(scope="session")
def cached_env(compile_cache_dir):
    """Environment for subprocesses that share the session's compilation cache."""
    values = {"jax_compilation_cache_dir": str(compile_cache_dir), "jax_persistent_cache_min_compile_time_secs": "0",
              "jax_persistent_cache_min_entry_size_bytes": "0"}
    return {**os.environ, **{_CACHE_OPTIONS[k]: v for k, v in values.items()}}


@pytest.fixture
def compile_cache(compile_cache_dir):
    """Use the session's compilation cache in this process for one test, then restore the settings."""
    try:
        from jax._src import (
            compilation_cache as cc,  # the only way to re-read the cache settings in-process
        )
    except ImportError:  # pragma: no cover - an internal module: without it the tests are only slower
        yield
        return
    old = {k: getattr(jax.config, k) for k in _CACHE_OPTIONS}
    jax.config.update("jax_compilation_cache_dir", str(compile_cache_dir))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    cc.reset_cache()
    try:
        yield
    finally:
        for k, v in old.items():
            jax.config.update(k, v)
        cc.reset_cache()
