"""Worker threads for the CPU kernels (numba, releasing the GIL): how many, and one pool they share.

The splat rasteriser's tile kernels (models/splat/tiles_numba.py) and the TSDF fusion kernel
(export/fusion_kernel.py) each split their work over worker threads; both ask here.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

_POOL: ThreadPoolExecutor | None = None


def cpu_count() -> int:
    """The CPUs this process may use (its affinity mask where the OS has one, else os.cpu_count())."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def pool(n: int) -> ThreadPoolExecutor:
    """The shared worker threads (at least n), started on first use."""
    global _POOL
    if _POOL is None or _POOL._max_workers < n:
        _POOL = ThreadPoolExecutor(n, thread_name_prefix="nerfkit")
    return _POOL


def run_interleaved(kernel, args: tuple, n: int) -> None:
    """kernel(*args, first, n) for first = 0 .. n - 1 on n worker threads (inline when n is 1): each call takes
    the items first, first + n, ... of the work, so the calls' shares are spread alike over it."""
    if n == 1:
        kernel(*args, 0, 1)
        return
    for job in [pool(n).submit(kernel, *args, first, n) for first in range(n)]:
        job.result()
