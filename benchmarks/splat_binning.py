"""The numba rasteriser's binning: its cost, the depth sort in it, and what keeping the forward's tile lists for
the backward saves.

    python benchmarks/splat_binning.py [--reps 10] [--out benchmarks/results/splat_binning.json]

Scenes: splat_raster.py's lego-like random Gaussians (50,000) at 200 and 800 px. Timed, interleaved, best and
median of --reps: the depth order as numpy's stable argsort and as tiles_numba.depth_order (the same order,
checked); tiles_numba.bin_gaussians; forward + backward binning twice (backward(bins=None)) and once
(forward(keep_bins=True) + backward(bins=token)).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from provenance import provenance
from splat_raster import lego_scene

from nerfkit.models.splat import tiles_numba


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results" / "splat_binning.json")
    a = ap.parse_args()
    rows = []
    for size in (200, 800):
        args = lego_scene(50_000, size, 0)
        means2d, conics, _, opacities, depths, radii, _ = args
        f64 = [np.ascontiguousarray(x, np.float64) for x in (means2d, conics, opacities)]
        radii = np.ascontiguousarray(radii, np.int32)
        live = np.flatnonzero(radii > 0)
        image, t_final, n_contrib = tiles_numba.forward(*args, size, size)
        g_img = np.random.default_rng(0).normal(size=image.shape).astype(np.float32)
        g_t = np.zeros_like(t_final)
        assert np.array_equal(tiles_numba.depth_order(depths, live), live[np.argsort(depths[live], kind="stable")])

        def twice():
            _, t, n = tiles_numba.forward(*args, size, size)
            tiles_numba.backward(*args, size, size, t, n, g_img, g_t)

        def once():
            _, t, n, token = tiles_numba.forward(*args, size, size, keep_bins=True)
            tiles_numba.backward(*args, size, size, t, n, g_img, g_t, bins=token)

        cands = {"argsort_stable": lambda: np.argsort(depths[live], kind="stable"),
                 "depth_order": lambda: tiles_numba.depth_order(depths, live),
                 "bin_gaussians": lambda: tiles_numba.bin_gaussians(*f64, depths, radii, size, size),
                 "forward_backward_binning_twice": twice, "forward_backward_binning_once": once}
        times = {k: [] for k in cands}
        for k, f in cands.items():
            f()  # compile / warm
        for _ in range(a.reps):
            for k, f in cands.items():
                t0 = time.perf_counter()
                f()
                times[k].append(1e3 * (time.perf_counter() - t0))
        row = {"size": size, "gaussians": 50_000, "live": int(live.size),
               "ms_best_median": {k: [round(min(v), 2), round(float(np.median(v)), 2)] for k, v in times.items()}}
        rows.append(row)
        print(size, {k: v[0] for k, v in row["ms_best_median"].items()}, flush=True)
    result = {"what": "numba rasteriser binning, its depth sort, and one vs two binnings per forward + backward "
                      "(lego-like 50k Gaussians, ms, best and median, interleaved)",
              "rows": rows, "provenance": provenance()}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
