"""The CPU tile rasteriser against the machine's limit: work counted, rate achieved, peak measured.

    python benchmarks/splat_roofline.py RUN [RUN ...] [--views 6] [--reps 5] [--name splat_roofline]

For each trained splat run (its Gaussians, at the run's image size) and `--views` training views evenly spaced:

work     pixel-Gaussian pairs, counted by a mirror of the kernels' loops (tiles_kernels.py): forward, the pairs
         tested (a pixel of a Gaussian's ellipse span, not yet done) and blended (the alpha test passed);
         backward, the pairs tested (k < the pixel's n_contrib) and blended; flops per pair from the kernels'
         arithmetic (FLOPS below: an exp, a division and a min count one flop each, as a roofline counts them);
         bytes from memory per pair: a Gaussian's 10 float64 parameters read once per tile it lands in, the
         image, T and n_contrib once per pixel (everything else lives in the tile's L1-resident arrays).
time     tiles_numba.forward and .backward (binning included, as a training step pays it), median of --reps,
         on every core and on one (parallel efficiency), and the binning alone.
machine  measured peaks (before and after the runs, the better of the two: the machine is shared): float64 and
         float32 matrix products (numpy's BLAS on every core: what the cores' vector units do at their best), a
         plain numba loop of independent multiply-adds over both cores (what numba's vectoriser reaches on easy
         code), and memory bandwidth (a numba triad over 3 x 96 MB arrays).

achieved = flops / time; attainable = min(peak, intensity x bandwidth) (the roofline); the gap is their ratio.
Writes benchmarks/results/<name>.json with its provenance.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from numba import njit, prange
from provenance import provenance

from nerfkit.models.splat import tiles_geometry, tiles_numba
from nerfkit.models.splat.gaussians import PARAM_NAMES, all_sh, band_mask, intrinsics_of, splat_inputs
from nerfkit.models.splat.reference import ALPHA_MAX, ALPHA_MIN, SIGMA_MAX, T_MIN
from nerfkit.models.splat.tiles_geometry import _INV_A, _OK, TILE, _cols, _entry, _rows, _tile_box
from nerfkit.rays.cameras import Camera
from nerfkit.run.folder import RunFolder

ROOT = Path(__file__).resolve().parents[1]

# Flops per pair, read off tiles_kernels.py's inner loops (3 colour channels):
#   tested: e *= r, r *= q (2); the 3-sigma cut e < E_MIN (1)
#   forward blended: alpha = min(ALPHA_MAX, o e) (2); next_t = T (1 - alpha) (2); w = alpha T (1);
#       acc += w c (6)
#   backward blended: d_x = m_x - (x0 + x + 0.5) (2); alpha (2); 1 / (1 - alpha) (2); t_k, w (2); per
#       channel g_col += w G, d_alpha += (c - R) G, R += alpha (c - R) (7 x 3); d_alpha t_k - g_end inv (3);
#       g_o += e d_alpha (2);
#       d_sigma = -alpha d_alpha (2); g_mx, g_my += d_sigma (a dx + b dy) (5 + 5); g_a, g_b, g_c (3 x 3)
FLOPS = {"tested": 3, "forward_blended": 11, "backward_blended": 55}
PARAM_BYTES = 17 * 8  # per Gaussian-tile entry: its gaussian_table row 13, colour 3, id (as 8)
PIXEL_BYTES = {"forward": 3 * 8 + 8 + 4, "backward": 3 * 8 + 8 + 4 + 8}  # image, T, n_contrib (+ dL/dT)


@njit(cache=False)
def _pair_passes(g, gt, x0, y0, nx, ny):
    """The pixels (y, x) of Gaussian g's ellipse span in the tile and whether each passes the alpha test
    (tiles_kernels._blend_tile's tests; gt: tiles_geometry.gaussian_table), as a list of (y, x, alpha or -1)."""
    res = []
    if gt[g, _OK] == 0.0:
        return res
    mx, my, a, b, c, o, det, span, _ = _entry(gt, g)
    ys, ye = _rows(my, a, det, span, y0, ny)
    for y in range(ys, ye + 1):
        dy = my - (y0 + y + 0.5)
        xs, xe = _cols(mx, dy, a, b, det, gt[g, _INV_A], span, x0, nx)
        for x in range(xs, xe + 1):
            dx = mx - (x0 + x + 0.5)
            sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
            alpha = min(ALPHA_MAX, o * math.exp(-sigma))
            res.append((y, x, alpha if (0.0 <= sigma <= SIGMA_MAX and alpha >= ALPHA_MIN) else -1.0))
    return res


@njit(cache=False)
def count_pairs(gt, offsets, ids, n_contrib, width, height):
    """(forward tested, forward blended, backward tested, backward blended, Gaussian-tile entries the forward
    pass visits, entries the backward pass visits): the kernels' loops (tiles_kernels._blend_tile,
    _unblend_tile) run with counters instead of arithmetic (the same tests, so the same pairs)."""
    tiles_x = (width + TILE - 1) // TILE
    f_test = f_blend = b_test = b_blend = f_entries = b_entries = 0
    for t in range(offsets.size - 1):
        x0, y0, nx, ny = _tile_box(t, tiles_x, width, height, TILE)
        start, count = offsets[t], offsets[t + 1] - offsets[t]
        trans = np.ones((TILE, TILE))
        done = np.zeros((TILE, TILE), np.bool_)
        n_live = nx * ny
        for k in range(count):  # forward, front to back, until every pixel is done
            f_entries += 1
            for y, x, alpha in _pair_passes(ids[start + k], gt, x0, y0, nx, ny):
                if done[y, x]:
                    continue
                f_test += 1
                if alpha < 0.0:
                    continue
                next_t = trans[y, x] * (1.0 - alpha)
                if next_t < T_MIN:
                    done[y, x] = True
                    n_live -= 1
                    continue
                f_blend += 1
                trans[y, x] = next_t
            if n_live == 0:
                break
        for k in range(n_contrib[y0:y0 + ny, x0:x0 + nx].max() - 1, -1, -1):  # backward, from the tile's largest n_contrib
            b_entries += 1
            for y, x, alpha in _pair_passes(ids[start + k], gt, x0, y0, nx, ny):
                if k >= n_contrib[y0 + y, x0 + x]:
                    continue
                b_test += 1
                b_blend += alpha >= 0.0
    return f_test, f_blend, b_test, b_blend, f_entries, b_entries


@njit(parallel=True, fastmath=True, cache=False)
def _fma_loop(x, reps):
    """x [workers, 64]: reps rounds of x = x 0.9999999 + 1e-9 per row, rows across the cores (2 flops each)."""
    for w in prange(x.shape[0]):
        v = x[w].copy()
        for _ in range(reps):
            for j in range(v.size):
                v[j] = v[j] * 0.9999999 + 1e-9
        x[w] = v


@njit(parallel=True, cache=False)
def _triad(a, b, c, s):
    for i in prange(a.size):
        a[i] = b[i] + s * c[i]


def _times(fn, reps: int) -> list[float]:
    """Seconds of `reps` calls of fn, after one untimed call (compilation, caches)."""
    fn()
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return ts


def _best(fn, reps: int) -> float:
    return min(_times(fn, reps))


def _median(fn, reps: int) -> float:
    return float(np.median(_times(fn, reps)))


def machine_peaks(reps: int = 5) -> dict:
    """Measured: GFLOP/s of BLAS matrix products (float64, float32; 2 n^3 flops), of the numba multiply-add
    loop, and the triad's GB/s (24 bytes moved per element: two reads, one write)."""
    out = {}
    for dt in (np.float64, np.float32):
        n = 2048
        a, b = np.random.default_rng(0).random((2, n, n)).astype(dt)
        out[f"blas_{np.dtype(dt).name}_gflops"] = round(2 * n ** 3 / _best(lambda: a @ b, reps) / 1e9, 1)
    workers = 64
    x = np.ones((workers, 64))
    r = 200_000
    out["numba_fma_float64_gflops"] = round(2 * x.size * r / _best(lambda: _fma_loop(x, r), reps) / 1e9, 1)
    n = 12_000_000
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    out["triad_gbs"] = round(24 * n / _best(lambda: _triad(a, b, c, 0.5), reps) / 1e9, 1)
    return out


def view_projector(run):
    """(inputs(view) -> the rasteriser's numpy inputs for training view `view` of a loaded run, (width, height)):
    the projection compiled once for the run, the pose an argument."""
    p = {k: jnp.asarray(v) for k, v in run.params.items() if k in PARAM_NAMES}
    cam = Camera.from_json(run.scene["camera"])
    w, h = cam.width, cam.height
    intr = jnp.asarray(intrinsics_of(cam), jnp.float32)
    project = jax.jit(lambda q, c2w: splat_inputs(q, c2w, (intr[0], intr[1], intr[2], intr[3]), w, h,
                                                  all_sh(q) * band_mask(3)))

    def inputs(view: int) -> tuple:
        proj, colors, opac = project(p, jnp.asarray(np.asarray(run.scene["train_poses"][view], np.float32)))
        arr = [np.asarray(x) for x in (proj["means2d"], proj["conics"], colors, opac, proj["depths"])]
        return (*arr, np.ascontiguousarray(proj["radii"], np.int32), np.ones(3, np.float32))

    return inputs, (w, h)


def measure_view(inputs, size: tuple[int, int], view: int, reps: int) -> dict:
    args, (w, h) = inputs(view), size
    means2d, conics, colors, opac, depths, radii, bg = args
    image, t_final, n_contrib = tiles_numba.forward(*args, w, h)
    g_img = np.random.default_rng(view).normal(size=image.shape).astype(np.float32) * 1e-3
    g_t = np.zeros_like(t_final)
    m64, c64, o64 = tiles_numba._f64(means2d, conics, opac)
    offsets, ids = tiles_numba.bin_gaussians(m64, c64, o64, depths, radii, w, h)
    gt = tiles_geometry.gaussian_table(m64, c64, o64, radii, h)
    f_test, f_blend, b_test, b_blend, f_entries, b_entries = count_pairs(gt, offsets, ids, n_contrib, w, h)
    times = {"forward_s": _median(lambda: tiles_numba.forward(*args, w, h), reps),
             "backward_s": _median(lambda: tiles_numba.backward(*args, w, h, t_final, n_contrib, g_img, g_t), reps),
             "forward_1thread_s": _median(lambda: tiles_numba.forward(*args, w, h, threads=1), reps),
             "backward_1thread_s": _median(lambda: tiles_numba.backward(*args, w, h, t_final, n_contrib, g_img, g_t,
                                                                        threads=1), reps),
             "binning_s": _median(lambda: tiles_numba.bin_local(m64, c64, o64, depths, radii, w, h, None), reps)}
    return {"view": view, "width": w, "height": h, "gaussians_live": int((radii > 0).sum()),
            "tile_entries": int(ids.size), "entries_visited": {"forward": int(f_entries), "backward": int(b_entries)},
            "pairs": {"forward_tested": int(f_test), "forward_blended": int(f_blend),
                      "backward_tested": int(b_test), "backward_blended": int(b_blend)},
            **{k: round(v, 5) for k, v in times.items()}}


def roofline(views: list[dict], peaks: dict) -> dict:
    """Totals over the views: flops, bytes, seconds per pass; achieved GFLOP/s and the attainable one."""
    out = {}
    for pas in ("forward", "backward"):
        tested = sum(v["pairs"][f"{pas}_tested"] for v in views)
        blended = sum(v["pairs"][f"{pas}_blended"] for v in views)
        flops = FLOPS["tested"] * tested + FLOPS[f"{pas}_blended"] * blended
        nbytes = sum(PARAM_BYTES * v["entries_visited"][pas] + PIXEL_BYTES[pas] * v["width"] * v["height"]
                     for v in views)
        secs = sum(v[f"{pas}_s"] for v in views)
        secs1 = sum(v[f"{pas}_1thread_s"] for v in views)
        intensity = flops / nbytes
        peak = peaks["blas_float64_gflops"]
        attainable = min(peak, intensity * peaks["triad_gbs"])
        achieved = flops / secs / 1e9
        out[pas] = {"pairs_tested": tested, "pairs_blended": blended, "gflop": round(flops / 1e9, 4),
                    "mbytes": round(nbytes / 1e6, 2), "flops_per_byte": round(intensity, 1),
                    "ms_per_view": round(1e3 * secs / len(views), 2),
                    "ns_per_tested_pair": round(1e9 * secs / tested, 2),
                    "pairs_per_entry": round(tested / sum(v["entries_visited"][pas] for v in views), 1),
                    "achieved_gflops": round(achieved, 2), "attainable_gflops": round(attainable, 1),
                    "gap": round(attainable / achieved, 1),
                    "numba_loop_gap": round(peaks["numba_fma_float64_gflops"] / achieved, 1),
                    "parallel_speedup": round(secs1 / secs, 2)}
    out["binning_share_of_forward"] = round(sum(v["binning_s"] for v in views) / sum(v["forward_s"] for v in views), 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", type=Path, nargs="+")
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--name", default="splat_roofline")
    a = ap.parse_args()
    before = machine_peaks()
    print("machine:", before, flush=True)
    measured = {}
    for path in a.runs:
        run = RunFolder(path).load()
        n_train = len(run.scene["train_poses"])
        inputs, size = view_projector(run)
        views = [measure_view(inputs, size, int(v), a.reps) for v in np.linspace(0, n_train - 1, a.views).round()]
        log = path / "metrics.jsonl"
        steps = json.loads(log.read_text().splitlines()[-1])["step"] if log.is_file() else None
        measured[str(path)] = {"gaussians": int(np.asarray(run.params["means"]).shape[0]), "trained_steps": steps,
                               "views": views}
    after = machine_peaks()  # the machine is shared: the peaks again, after; the roofline takes the better
    peaks = {k: max(before[k], after[k]) for k in before}
    result = {"what": __doc__.split("\n\n")[0], "flops_per_pair": FLOPS, "machine": peaks,
              "machine_before_after": [before, after], "runs": {}, "provenance": provenance()}
    for path, m in measured.items():
        result["runs"][path] = m | {"roofline": roofline(m["views"], peaks)}
        print(path, json.dumps(result["runs"][path]["roofline"], indent=1), flush=True)
    out = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    out.write_text(json.dumps(result, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
