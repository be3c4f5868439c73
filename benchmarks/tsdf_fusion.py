"""TSDF fusion's speed on the CPU: the numba kernel (export/fusion_kernel.py) against the XLA scan it replaced
there (tsdf.fuse_points), on the same views, and how far apart their sums are.

    python benchmarks/tsdf_fusion.py [--views 50] [--size 256] [--grid 128 256] [--repeats 3]

The views are exact z-depth maps of a unit sphere from a ring of cameras 4 units away (opacity 1 on the sphere, 0
off it), what a trained object's renders look like to the fusion. Each kernel fuses each grid once to compile,
then --repeats times; the record keeps the best time and the rate in point-views a second (grid points x views /
seconds), and how many points' sums differ beyond float32 rounding. Writes benchmarks/results/tsdf_fusion.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def sphere_views(n_views: int, size: int):
    """(c2w [V, 4, 4], intrinsics [V, 4], z-depth [V, S, S], opacity [V, S, S]) float32 of a unit sphere."""
    from nerfkit.data.procedural.scene import look_at

    angles = np.linspace(0, 2 * np.pi, n_views, endpoint=False)
    c2w = np.stack([look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 1.5 + 0.5 * np.sin(3 * a)])) for a in angles])
    focal = 1.2 * size
    j, i = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    d_cam = np.stack([(j - size / 2) / focal, -(i - size / 2) / focal, -np.ones_like(j)], -1)  # z = -1: t is z-depth
    depth, opacity = np.full((n_views, size, size), 10.0), np.zeros((n_views, size, size))
    for k, pose in enumerate(c2w):
        d, o = d_cam @ pose[:3, :3].T, pose[:3, 3]
        a, b, c = np.sum(d * d, -1), 2 * d @ o, o @ o - 1.0
        disc = b * b - 4 * a * c
        hit = disc > 0
        depth[k][hit] = ((-b - np.sqrt(np.where(hit, disc, 0))) / (2 * a))[hit]
        opacity[k][hit] = 1.0
    intr = np.tile([focal, focal, size / 2, size / 2], (n_views, 1))
    return tuple(x.astype(np.float32) for x in (c2w, intr, depth, opacity))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--views", type=int, default=50)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--grid", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    from nerfkit.export import tsdf

    views = sphere_views(a.views, a.size)
    record = {"provenance": provenance(), "views": a.views, "size": a.size, "grids": []}
    for n in a.grid:
        axis = tsdf.grid_axis(1.5, n)
        row, sums = {"grid": n}, {}
        for kernel in ("xla", "numba"):
            sums[kernel] = tsdf.fuse_grid(axis, *views, 0.035, kernel=kernel)  # compiles
            best = min(_timed(tsdf.fuse_grid, axis, *views, 0.035, kernel=kernel) for _ in range(a.repeats))
            row[kernel] = {"seconds": round(best, 3), "point_views_per_s": round(a.views * n**3 / best)}
            print(f"{n}^3, {a.views} views, {kernel}: {best:.2f} s, {a.views * n**3 / best / 1e6:.0f} M point-views/s")
        pairs = list(zip(("fsum", "wsum", "seen"), sums["xla"], sums["numba"]))
        row["max_abs_difference"] = {name: float(np.max(np.abs(x - y))) for name, x, y in pairs}
        # points whose sums differ by more than float32 rounding: a projection within rounding of a pixel's edge
        # (or the image's) reads the neighbouring pixel (or none) in one of the two
        row["share_differing"] = {name: float(np.mean(np.abs(x - y) > 1e-4 * (1 + np.abs(x)))) for name, x, y in pairs}
        row["speedup"] = round(row["xla"]["seconds"] / row["numba"]["seconds"], 2)
        record["grids"].append(row)
    a.results.mkdir(parents=True, exist_ok=True)
    out = a.results / "tsdf_fusion.json"
    out.write_text(json.dumps(record, indent=1))
    print(f"wrote {out}")


def _timed(fn, *args, **kwargs) -> float:
    t0 = time.perf_counter()
    fn(*args, **kwargs)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
