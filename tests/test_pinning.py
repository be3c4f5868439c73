"""Each test process runs on a share of the cores of its own (pinning.py, called by conftest.py as it starts)."""

import os

import pytest
from pinning import cpu_share, pin_worker

needs_affinity = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="this OS has no CPU affinity masks")


def test_the_cpus_are_shared_out_in_runs():
    cpus = [0, 1, 2, 3, 4, 5, 6, 7]
    assert [cpu_share(cpus, k, 4) for k in range(4)] == [[0, 1], [2, 3], [4, 5], [6, 7]]
    assert [cpu_share(cpus, k, 3) for k in range(3)] == [[0, 1], [2, 3, 4], [5, 6, 7]]
    assert [cpu_share([2, 5], k, 2) for k in range(2)] == [[2], [5]]
    assert [cpu_share([2, 5], k, 3) for k in range(3)] == [[2], [5], [2]]  # more processes than CPUs


@needs_affinity
def test_a_test_process_has_its_own_cpus():
    """Under pytest-xdist this process was pinned as it started to its share (or it may use one CPU only)."""
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 0)
    if count < 2:
        pytest.skip("not one of several pytest-xdist test processes (-n 0 or 1): nothing is pinned")
    every = os.cpu_count() or 1
    assert len(os.sched_getaffinity(0)) <= max(1, -(-every // count))


@needs_affinity
def test_worker_k_takes_its_share():
    mine = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, range(os.cpu_count() or 1))  # every CPU this process may be given
        cpus = sorted(os.sched_getaffinity(0))
        if len(cpus) < 2:
            pytest.skip("one CPU: nothing to pin")
        assert pin_worker("gw1", str(len(cpus))) == {cpus[1]} == os.sched_getaffinity(0)
        os.sched_setaffinity(0, cpus)
        assert pin_worker("gw0", "2") == set(cpus[: len(cpus) // 2]) == os.sched_getaffinity(0)
        for worker, count in ((None, "2"), ("gw1", None), ("gw1", "1")):  # not one of several test processes
            os.sched_setaffinity(0, cpus)
            assert pin_worker(worker, count) is None and sorted(os.sched_getaffinity(0)) == cpus
        os.sched_setaffinity(0, cpus[:1])
        assert pin_worker("gw1", "2") is None and os.sched_getaffinity(0) == {cpus[0]}
    finally:
        os.sched_setaffinity(0, mine)
