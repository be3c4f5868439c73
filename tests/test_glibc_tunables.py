"""The suite's malloc tunable (glibc_tunables.py): added where $GLIBC_TUNABLES does not name it and glibc knows it,
and present in this test process's environment as the process started (conftest.py ran before pytest-xdist
started it), which is the only time glibc reads it."""

import os
from pathlib import Path

import glibc_tunables as tun
import pytest


def test_the_tunable_is_added_once_and_the_users_choice_wins(monkeypatch):
    monkeypatch.setattr(tun, "_glibc", lambda: (2, 36))
    env = {}
    assert tun.suite_tunables(env) == "glibc.malloc.hugetlb=1"
    assert env["GLIBC_TUNABLES"] == "glibc.malloc.hugetlb=1"
    assert tun.suite_tunables(env) is None and env["GLIBC_TUNABLES"].count(tun.TUNABLE) == 1
    other = {"GLIBC_TUNABLES": "glibc.malloc.arena_max=2"}
    tun.suite_tunables(other)
    assert other["GLIBC_TUNABLES"] == "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1"
    mine = {"GLIBC_TUNABLES": "glibc.malloc.hugetlb=0"}
    assert tun.suite_tunables(mine) is None and mine["GLIBC_TUNABLES"] == "glibc.malloc.hugetlb=0"


def test_an_older_glibc_or_another_c_library_gets_none(monkeypatch):
    for version in ((2, 31), (2, 34), None):
        monkeypatch.setattr(tun, "_glibc", lambda v=version: v)
        env = {}
        assert tun.suite_tunables(env) is None and env == {}
    monkeypatch.undo()
    assert tun._glibc() is None or len(tun._glibc()) == 2  # this process's, read from platform.libc_ver


@pytest.mark.skipif(not os.environ.get("PYTEST_XDIST_WORKER"), reason="only the test processes pytest-xdist starts "
                    "after conftest.py get it; this one was started before")
def test_this_test_process_started_with_it():
    started = Path("/proc/self/environ")
    if tun._glibc() is None or tun._glibc() < tun.FIRST_GLIBC or not started.exists():
        pytest.skip("not a glibc >= 2.35 process with /proc")
    env = dict(item.split(b"=", 1) for item in started.read_bytes().split(b"\0") if b"=" in item)
    assert tun.TUNABLE.encode() in env.get(b"GLIBC_TUNABLES", b"")
