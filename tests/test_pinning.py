"""Each test process runs on a core of its own (pinning.py, called by conftest.py as the process starts)."""

import os

import pytest
from pinning import pin_worker

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="this OS has no CPU affinity masks")


def test_a_test_process_has_one_core():
    """Under pytest-xdist this process was pinned as it started (or the machine lets it use one CPU only)."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        pytest.skip("not a pytest-xdist test process (-n 0): nothing is pinned")
    assert len(os.sched_getaffinity(0)) == 1


def test_worker_k_takes_the_k_th_cpu():
    mine = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, range(os.cpu_count() or 1))  # every CPU this process may be given
        cpus = sorted(os.sched_getaffinity(0))
        if len(cpus) < 2:
            pytest.skip("one CPU: nothing to pin")
        assert pin_worker("gw1") == {cpus[1]} == os.sched_getaffinity(0)
        os.sched_setaffinity(0, cpus)
        assert pin_worker(f"gw{len(cpus)}") == {cpus[0]} == os.sched_getaffinity(0)  # more processes than CPUs
        os.sched_setaffinity(0, cpus)
        assert pin_worker(None) is None and sorted(os.sched_getaffinity(0)) == cpus
        os.sched_setaffinity(0, cpus[:1])
        assert pin_worker("gw1") is None and os.sched_getaffinity(0) == {cpus[0]}
    finally:
        os.sched_setaffinity(0, mine)
