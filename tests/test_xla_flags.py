"""The suite's XLA flags (xla_flags.py): added where $XLA_FLAGS does not name them and jaxlib knows them, present in
this test process's $XLA_FLAGS (conftest.py), and not set by importing nerfkit (users get XLA's defaults)."""

import os

import xla_flags as xla


SUITE = "--xla_cpu_use_fusion_emitters=false --xla_backend_optimization_level=1"


def test_the_flags_are_added_once_and_the_users_choice_wins():
    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    assert xla.suite_flags(env) == SUITE
    assert env["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=2 {SUITE}"
    assert xla.suite_flags(env) is None and all(env["XLA_FLAGS"].count(f) == 1 for f in xla.FLAGS)
    mine = {"XLA_FLAGS": "--xla_cpu_use_fusion_emitters=true"}
    assert xla.suite_flags(mine) == "--xla_backend_optimization_level=1"
    assert mine["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=true --xla_backend_optimization_level=1"
    both = {"XLA_FLAGS": "--xla_backend_optimization_level=2 --xla_cpu_use_fusion_emitters=true"}
    assert xla.suite_flags(both) is None and both["XLA_FLAGS"].count("=") == 2
    empty = {}
    xla.suite_flags(empty)
    assert empty["XLA_FLAGS"] == SUITE


def test_a_jaxlib_that_does_not_know_the_flag_gets_none(monkeypatch):
    """An unknown flag in $XLA_FLAGS aborts the process, so older jaxlibs (0.4.35 is the lowest allowed) get none."""
    assert xla._version("0.5.3.dev20250101") == (0, 5, 3) and xla._version("0.10.2") == (0, 10, 2)
    for version, added in (("0.4.35", False), ("0.5.0", False), ("0.5.3", True), ("0.10.2", True)):
        monkeypatch.setattr(xla.metadata, "version", lambda _name, v=version: v)
        env = {}
        assert (xla.suite_flags(env) is not None) == added and ("XLA_FLAGS" in env) == added


def test_this_process_has_it_in_its_environment():
    from importlib import metadata

    if xla._version(metadata.version("jaxlib")) >= xla.FIRST_JAXLIB:
        assert all(f in os.environ["XLA_FLAGS"] for f in xla.FLAGS)


def test_importing_nerfkit_leaves_xla_flags_alone():
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    out = subprocess.run([sys.executable, "-c", "import os, nerfkit, nerfkit.cli.main; print(os.environ.get('XLA_FLAGS'))"],
                         env=env, capture_output=True, text=True, check=True).stdout.strip()
    assert out == "None"
