"""The command line's restart with transparent huge pages for malloc's large blocks (cli/hugepages.py): when it
restarts, with what, that a restarted verb answers as before, and that the suite's test processes start with the
tunable (conftest.py)."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from nerfkit.cli import hugepages, main
from nerfkit.core.interrupts import BLOCKED, SIGNALS

ON = "glibc.malloc.hugetlb=1"


def test_the_tunable_is_added_once_where_glibc_and_the_kernel_use_it():
    assert hugepages.huge_page_environment({"A": "1"}, (2, 36), "madvise") == {"A": "1", "GLIBC_TUNABLES": ON}
    assert hugepages.huge_page_environment({}, (2, 35), "always") == {"GLIBC_TUNABLES": ON}
    other = hugepages.huge_page_environment({"GLIBC_TUNABLES": "glibc.malloc.arena_max=2"}, (2, 36), "madvise")
    assert other["GLIBC_TUNABLES"] == "glibc.malloc.arena_max=2:" + ON
    for env, glibc, thp in (({"GLIBC_TUNABLES": ON}, (2, 36), "madvise"),  # already there: no loop of restarts
                            ({"GLIBC_TUNABLES": "glibc.malloc.hugetlb=0"}, (2, 36), "madvise"),  # the user's choice
                            ({"NERFKIT_HUGEPAGES": "off"}, (2, 36), "madvise"),
                            ({}, (2, 34), "madvise"), ({}, None, "madvise"),  # an older glibc, another C library
                            ({}, (2, 36), "never"), ({}, (2, 36), None)):  # no transparent huge pages
        assert hugepages.huge_page_environment(env, glibc, thp) is None, (env, glibc, thp)


def test_the_glibc_version_is_read_whatever_its_suffix(monkeypatch):
    for libc, version in ((("glibc", "2.36"), (2, 36)), (("glibc", "2.35.9000-dev"), (2, 35)), (("glibc", "2"), None),
                          (("glibc", ""), None), (("musl", "1.2.4"), None), (("", ""), None)):
        monkeypatch.setattr(hugepages.platform, "libc_ver", lambda v=libc: v)
        assert hugepages.glibc_version() == version, libc


def test_the_kernel_mode_is_read_from_its_brackets(tmp_path, monkeypatch):
    for text, mode in (("always [madvise] never\n", "madvise"), ("[always] madvise never\n", "always"),
                       ("always madvise [never]\n", "never")):
        (tmp_path / "enabled").write_text(text)
        monkeypatch.setattr(hugepages, "THP", tmp_path / "enabled")
        assert hugepages.thp_mode() == mode
    monkeypatch.setattr(hugepages, "THP", tmp_path / "missing")
    assert hugepages.thp_mode() is None


def test_a_compiling_verb_from_the_command_line_restarts_with_the_same_arguments(monkeypatch, tmp_path):
    execs = []

    def fake_execve(path, args, env):
        execs.append((path, args, env))
        raise OSError("not here")  # a failed restart: the verb goes on in this process

    monkeypatch.setattr(hugepages.os, "execve", fake_execve)
    monkeypatch.setattr(hugepages.sys, "platform", "linux")
    monkeypatch.setattr(hugepages, "glibc_version", lambda: (2, 36))
    monkeypatch.setattr(hugepages, "thp_mode", lambda: "madvise")
    monkeypatch.delenv("GLIBC_TUNABLES", raising=False)
    monkeypatch.delenv("NERFKIT_HUGEPAGES", raising=False)
    missing = str(tmp_path / "no_run")
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "nerfkit", "eval", missing])
    monkeypatch.setattr(sys, "argv", ["nerfkit", "eval", missing])
    assert main.main() == 1  # the restart failed, the verb answered in this process
    # (SIGINT and SIGTERM blocked across the exec, and the new process told to unblock them: interrupts.py)
    assert execs == [(sys.executable, [sys.executable, "-m", "nerfkit", "eval", missing],
                      {**os.environ, "GLIBC_TUNABLES": ON, BLOCKED: "1"})]
    assert not set(SIGNALS) & signal.pthread_sigmask(signal.SIG_BLOCK, [])  # unblocked again: the exec failed
    assert main.main(["eval", missing]) == 1 and len(execs) == 1  # a caller's main(argv): never restarted
    monkeypatch.setattr(sys, "argv", ["nerfkit", "eval", "--help"])
    with pytest.raises(SystemExit):
        main.main()  # help: no restart
    monkeypatch.setattr(sys, "argv", ["nerfkit", "make-scene", "--help"])
    with pytest.raises(SystemExit):
        main.main()
    assert len(execs) == 1


# `python -c CODE`: an audit hook says when the process replaces itself, then the CLI runs as `python -m nerfkit`
# does; a restart runs CODE again, with the tunable this time.
RUN_CLI = """import runpy, sys
sys.addaudithook(lambda event, args: event == "os.exec" and print("restarting", file=sys.stderr, flush=True))
sys.argv = ["nerfkit", *sys.argv[1:]]
runpy.run_module("nerfkit", run_name="__main__")
"""


def test_a_restarted_verb_answers_as_before(tmp_path):
    """The real restart (where this machine's glibc and kernel use the tunable) against none: one restart, then the
    same one-line error, exit status and nothing on stdout."""
    if hugepages.huge_page_environment({}, hugepages.glibc_version(), hugepages.thp_mode()) is None:
        pytest.skip("this machine's glibc or kernel would not use the tunable")
    missing = str(tmp_path / "no_run")
    base = {k: v for k, v in os.environ.items() if k not in ("GLIBC_TUNABLES", "NERFKIT_HUGEPAGES")}
    outs = []
    for extra in ({}, {"NERFKIT_HUGEPAGES": "off"}):
        r = subprocess.run([sys.executable, "-c", RUN_CLI, "eval", missing], env={**base, **extra},
                           capture_output=True, text=True, timeout=120)
        outs.append((r.returncode, r.stdout, r.stderr))
    restarted, alone = outs
    assert restarted[2].startswith("restarting\n") and restarted[2].count("restarting") == 1, restarted
    assert (restarted[0], restarted[1], restarted[2].removeprefix("restarting\n")) == alone, outs
    assert alone[0] == 1 and alone[1] == "" and "no_run" in alone[2] and alone[2].count("\n") == 1, alone


@pytest.mark.skipif(not os.environ.get("PYTEST_XDIST_WORKER"), reason="only the test processes pytest-xdist starts "
                    "after conftest.py get the tunable; this one was started before it ran")
def test_this_test_process_started_with_the_tunable():
    started = Path("/proc/self/environ")
    if hugepages.huge_page_environment({}, hugepages.glibc_version(), hugepages.thp_mode()) is None:
        pytest.skip("this machine's glibc or kernel would not use the tunable")
    env = dict(item.split(b"=", 1) for item in started.read_bytes().split(b"\0") if b"=" in item)
    assert ON.encode() in env.get(b"GLIBC_TUNABLES", b"")
