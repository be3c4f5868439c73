"""nerfkit's default XLA flags: added where the user has not named them and jaxlib knows them, and present in this
test process's $XLA_FLAGS (set when the suite imported nerfkit; whether XLA read them is shown by timing, in
core/xla.py's docstring, not here)."""

import os

from nerfkit.core import xla


def test_the_flag_is_added_once_and_the_users_choice_wins():
    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    assert xla.default_flags(env) == "--xla_cpu_use_fusion_emitters=false"
    assert env["XLA_FLAGS"] == "--xla_force_host_platform_device_count=2 --xla_cpu_use_fusion_emitters=false"
    assert xla.default_flags(env) is None and env["XLA_FLAGS"].count(xla.FLAG) == 1
    mine = {"XLA_FLAGS": "--xla_cpu_use_fusion_emitters=true"}
    assert xla.default_flags(mine) is None and mine["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=true"
    empty = {}
    xla.default_flags(empty)
    assert empty["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=false"


def test_a_jaxlib_that_does_not_know_the_flag_gets_none(monkeypatch):
    """An unknown flag in $XLA_FLAGS aborts the process, so older jaxlibs (0.4.35 is the lowest allowed) get none."""
    assert xla._version("0.5.3.dev20250101") == (0, 5, 3) and xla._version("0.10.2") == (0, 10, 2)
    for version, added in (("0.4.35", False), ("0.5.0", False), ("0.5.3", True), ("0.10.2", True)):
        monkeypatch.setattr(xla.metadata, "version", lambda _name, v=version: v)
        env = {}
        assert (xla.default_flags(env) is not None) == added and ("XLA_FLAGS" in env) == added


def test_this_process_has_it_in_its_environment():
    from importlib import metadata

    if xla._version(metadata.version("jaxlib")) >= xla.FIRST_JAXLIB:
        assert xla.FLAG in os.environ["XLA_FLAGS"]
