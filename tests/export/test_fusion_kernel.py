"""The CPU fusion kernel (export/fusion_kernel.py) against tsdf.fuse_points, the XLA reference: the same sums on
exact depth maps of a sphere (test_tsdf.py's views) and on noisy ones, whatever the number of worker threads."""

from __future__ import annotations

import numpy as np
import pytest
from test_tsdf import cameras, exact_view

from nerfkit.export import fusion_kernel, tsdf

FOCAL, SIZE = 70.0, 64


def views(noisy: bool):
    poses = cameras([-20, 15, 50], 6).astype(np.float32)
    maps = [exact_view(p) for p in poses]
    depth, opacity = np.stack([m[0] for m in maps]), np.stack([m[1] for m in maps])
    if noisy:  # depth jitter across the truncation band, and soft opacities on both sides of A_FREE
        rng = np.random.default_rng(0)
        depth = (depth + rng.normal(0.0, 0.05, depth.shape)).astype(np.float32)
        opacity = np.clip(opacity - rng.uniform(0.0, 0.7, opacity.shape), 0.0, 1.0).astype(np.float32)
    intr = np.tile([FOCAL, FOCAL, SIZE / 2, SIZE / 2], (len(poses), 1)).astype(np.float32)
    return poses, intr, depth, opacity


@pytest.mark.parametrize("noisy", [False, True])
def test_the_kernel_sums_what_the_reference_sums(noisy):
    poses, intr, depth, opacity = views(noisy)
    axis = np.linspace(-1.0, 1.0, 40, dtype=np.float32)  # 64,000 points
    ref = tsdf.fuse_grid(axis, poses, intr, depth, opacity, 0.05, kernel="xla")
    got = tsdf.fuse_grid(axis, poses, intr, depth, opacity, 0.05, kernel="numba")
    # cases of every kind: points in some views' images and not in others', inside the sphere (W = 0) and not
    assert ref[2].min() < ref[2].max() <= len(poses) and 0 < (ref[1] > 0).mean() < 1
    for r, g in zip(ref, got):
        close = np.abs(r - g) <= 1e-4 * (1 + np.abs(r))
        # the same terms in float32, summed in the same order; a point whose projection falls within rounding of a
        # pixel edge may read the neighbouring pixel (measured here: no point differs, either way; on larger grids
        # about one in a million, benchmarks/tsdf_fusion.py), so the noisy maps leave a little room
        assert close.mean() >= (1.0 if not noisy else 0.999), (close.mean(), np.abs(r - g).max())


def test_the_sums_do_not_depend_on_the_threads(monkeypatch):
    poses, intr, depth, opacity = views(True)
    axis = np.linspace(-1.0, 1.0, 24, dtype=np.float32)
    cams = fusion_kernel.camera_table(poses, intr)
    outs, used = [], []
    run = fusion_kernel.run_interleaved
    monkeypatch.setattr(fusion_kernel, "run_interleaved",
                        lambda kernel, args, n: used.append(n) or run(kernel, args, n))
    for workers in (1, 3):
        monkeypatch.setattr(fusion_kernel, "cpu_count", lambda w=workers: w)
        out = tuple(np.full((24, 24, 24), np.nan, np.float32) for _ in range(3))
        fusion_kernel.fuse_lines(axis, 0, 24, cams, depth, opacity, 0.05, tsdf.A_FREE, out)
        outs.append(out)
    assert used == [1, 3]  # the lines went to one thread, then to three
    for a, b in zip(*outs):
        assert np.isfinite(a).all() and np.array_equal(a, b)  # every line written, by whichever thread
