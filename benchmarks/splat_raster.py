"""Speed of the 3DGS tile rasteriser candidates on a CPU: numba (the default), Warp's CPU backend, padded XLA.

    python benchmarks/splat_raster.py [--reps 3] [--quick] [--no-xla-large] [--out benchmarks/results/splat_raster.json]

Scenes: N random Gaussians of lego-like sizes (means uniform in the lego box [-0.7, 0.7] x
[-1.1, 1.1] x [-0.4, 1.0], scales log-normal around 0.01 (sd 0.5 in log), random rotations,
opacities sigmoid(1.5 z), random colours) seen by the Blender lego camera (distance 4, focal
1111 px at 800 px, scaled at 200 px), projected with project.project_gaussians; two views
per size ("frames"). Every candidate renders the same frames (XLA: frame 0 only, one timed rep, as one call takes
seconds; skipped past XLA_MAX_WORK padded alpha evaluations per frame); repetitions are interleaved
(candidate after candidate) so load from other processes on the shared machine hits all
alike; the JSON keeps min and median ms per frame.

forward: host forward incl. binning (numba, warp); jitted forward (xla).
backward: host backward incl. re-binning (numba, warp); jitted grad minus forward (xla).
numba_jax: the numba kernels through rasterize() under jax.jit: forward, and grad of a loss
(forward + backward + callback transfers), i.e. what a training step pays.
cpu_ratio: process CPU time / wall time during the candidate's runs (threads actually used).

Profile (numba, largest frame): binning share, 1 vs all threads, and with `perf` on PATH a
sampled breakdown (perf record -e cpu-clock) by shared object: the JIT blend code, libm
(exp), numpy (the depth argsort), the threading runtime.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numba
import numpy as np

from provenance import provenance

from nerfkit.models.splat import tiles_geometry, tiles_numba
from nerfkit.models.splat.project import project_gaussians
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.rays.cameras import look_at

CONFIGS = [(200, 50_000), (200, 200_000), (800, 50_000), (800, 200_000)]
XLA_MAX_WORK = 4e8  # the padded XLA candidate is skipped past this many alpha evaluations per frame


def lego_scene(n: int, size: int, view: int, seed: int = 0):
    """Projected random Gaussians (numpy float32): means2d, conics, colors, opacities, depths, radii, background."""
    rng = np.random.default_rng(seed)
    means = rng.uniform([-0.7, -1.1, -0.4], [0.7, 1.1, 1.0], (n, 3)).astype(np.float32)
    log_scales = (np.log(0.01) + 0.5 * rng.normal(size=(n, 3))).astype(np.float32)
    quats = rng.normal(size=(n, 4)).astype(np.float32)
    opacities = (1.0 / (1.0 + np.exp(-1.5 * rng.normal(size=n)))).astype(np.float32)
    colors = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    az = 0.6 + 2.1 * view
    eye = 4.0 * np.array([np.cos(0.5) * np.cos(az), np.cos(0.5) * np.sin(az), np.sin(0.5)])
    f = 1111.1111 * size / 800
    p = jax.jit(project_gaussians, static_argnums=(5, 6))(means, log_scales, quats, look_at(eye, np.zeros(3)),
                                                         (f, f, size / 2, size / 2), size, size)
    return (np.asarray(p["means2d"]), np.asarray(p["conics"]), colors, opacities, np.asarray(p["depths"]),
            np.asarray(p["radii"]), np.zeros(3, np.float32))


def scene_stats(args, size: int) -> dict:
    m, q, col, op, dep, rad, bg = args
    f64 = [np.asarray(a, np.float64) for a in (m, q, op)]
    offsets, ids = tiles_numba.bin_gaussians(*f64, dep, rad, size, size)
    lens = np.diff(offsets)
    _, t_final, n_contrib = tiles_numba.forward(*args, size, size)
    return {"live": int((rad > 0).sum()), "mean_radius_px": float(rad[rad > 0].mean()), "tile_overlaps": int(ids.size),
            "max_per_tile": int(lens.max()), "mean_per_tile": float(lens.mean()),
            "mean_n_contrib": float(n_contrib.mean()), "mean_T_final": float(t_final.mean()),
            "frac_pixels_T_below_1e-3": float((t_final < 1e-3).mean())}


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def next_pow2(x: int) -> int:
    return 1 << max(0, int(x - 1).bit_length())


class Candidate:
    """fwd(frame) and bwd(frame) callables over prepared frames; prepare() compiles / warms up."""

    def __init__(self, name, fwd, bwd):
        self.name, self.fwd, self.bwd = name, fwd, bwd


def host_candidate(name, module, frames, size):
    state = {}

    def fwd(i):
        state[i] = module.forward(*frames[i], size, size)

    def bwd(i):
        img, t_final, n_contrib = state[i]
        rng = np.random.default_rng(i)
        g_img = rng.normal(size=img.shape).astype(np.float32)
        module.backward(*frames[i], size, size, t_final, n_contrib, g_img, np.zeros_like(t_final))

    return Candidate(name, fwd, bwd)


def xla_candidate(frames, size):
    from splat_alt_xla import rasterize_xla, tile_rects

    budgets = []
    for m, q, col, op, dep, rad, bg in frames:  # exact budgets: longest list and overlap count (radius squares)
        rects = np.stack([np.asarray(r) for r in tile_rects(jnp.asarray(m), jnp.asarray(rad), size, size)], -1)
        order = np.argsort(dep, kind="stable").astype(np.int32)
        tiles_x = -(-size // tiles_numba.TILE)
        offsets, _ = tiles_geometry.bin_tiles(rects, order, tiles_x * tiles_x, tiles_x)
        budgets.append((int(np.diff(offsets).max()), int(offsets[-1])))
    k_max, m_max = next_pow2(max(b[0] for b in budgets)), next_pow2(max(b[1] for b in budgets))
    work = (-(-size // tiles_numba.TILE)) ** 2 * tiles_numba.TILE ** 2 * k_max  # alpha evaluations per frame
    if work > XLA_MAX_WORK:
        return {"skipped": f"{work:.2e} pixel-Gaussian pairs per frame (max_per_tile {k_max}) > {XLA_MAX_WORK:.0e}",
                "max_per_tile": k_max, "max_overlaps": m_max}
    fwd_j = jax.jit(lambda *a: rasterize_xla(*a, size, size, k_max, m_max))

    def loss(m, q, col, op, dep, rad, bg, g):
        return jnp.sum(rasterize_xla(m, q, col, op, dep, rad, bg, size, size, k_max, m_max)[0] * g)

    grad_j = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 6)))
    dev = [tuple(jnp.asarray(a) for a in f) for f in frames]
    gs = [jnp.asarray(np.random.default_rng(i).normal(size=(size, size, 3)).astype(np.float32))
          for i in range(len(frames))]
    times = {}

    def fwd(i):
        t = time.perf_counter()
        jax.block_until_ready(fwd_j(*dev[i]))
        times[i] = time.perf_counter() - t

    def bwd(i):  # grad = forward + backward; report the difference with this rep's forward
        jax.block_until_ready(grad_j(*dev[i], gs[i]))

    c = Candidate("xla", fwd, bwd)
    c.frames, c.reps = 1, 1  # seconds to minutes per call: one frame, one timed rep
    c.budget = {"max_per_tile": k_max, "max_overlaps": m_max}
    c.fwd_times = times
    return c


def numba_jax_candidate(frames, size):
    f = jax.jit(lambda *a: rasterize(*a, size, size, backend="numba"))

    def loss(m, q, col, op, dep, rad, bg, g):
        return jnp.sum(rasterize(m, q, col, op, dep, rad, bg, size, size, backend="numba")[0] * g)

    grad_j = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 6)))
    dev = [tuple(jnp.asarray(a) for a in fr) for fr in frames]
    gs = [jnp.asarray(np.random.default_rng(i).normal(size=(size, size, 3)).astype(np.float32))
          for i in range(len(frames))]
    return Candidate("numba_jax", lambda i: jax.block_until_ready(f(*dev[i])),
                     lambda i: jax.block_until_ready(grad_j(*dev[i], gs[i])))


def time_candidates(cands, n_frames, reps):
    res = {c.name: {"forward": [], "backward": [], "cpu": 0.0, "wall": 0.0} for c in cands}
    for c in cands:  # warm-up / compile
        for i in range(getattr(c, "frames", n_frames)):
            c.fwd(i)
            c.bwd(i)
    for rep in range(reps):
        for c in cands:
            if rep >= getattr(c, "reps", reps):
                continue
            for i in range(getattr(c, "frames", n_frames)):
                w0, p0 = time.perf_counter(), time.process_time()
                c.fwd(i)
                w1 = time.perf_counter()
                c.bwd(i)
                w2, p2 = time.perf_counter(), time.process_time()
                fwd_t = c.fwd_times[i] if hasattr(c, "fwd_times") else w1 - w0
                res[c.name]["forward"].append(fwd_t)
                res[c.name]["backward"].append((w2 - w1) - (fwd_t if c.name == "xla" else 0.0))
                res[c.name]["cpu"] += p2 - p0
                res[c.name]["wall"] += w2 - w0
    out = {}
    for name, r in res.items():
        out[name] = {f"{k}_ms_{s}": round(float(fn(r[k])) * 1e3, 1)
                     for k in ("forward", "backward") for s, fn in (("min", np.min), ("median", np.median))}
        out[name]["cpu_ratio"] = round(r["cpu"] / r["wall"], 2)
        out[name]["samples"] = len(r["forward"])
        if name == "numba_jax":  # its "backward" is the whole grad call
            out[name] = {k.replace("backward", "grad"): v for k, v in out[name].items()}
    return out


def perf_breakdown(fn, seconds: float = 2.0) -> dict | None:
    """Share of cpu-clock samples per shared object while fn() runs in a loop (None without perf)."""
    if shutil.which("perf") is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "perf.data")
        proc = subprocess.Popen(["perf", "record", "-q", "-e", "cpu-clock", "-F", "999", "-p", str(os.getpid()),
                                 "-o", data], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(0.5)
        t_end = time.perf_counter() + seconds
        while time.perf_counter() < t_end:
            fn()
        proc.send_signal(2)
        proc.wait()
        rep = subprocess.run(["perf", "report", "-i", data, "--sort", "dso", "--stdio", "-q"], capture_output=True,
                             text=True).stdout
    shares = {}
    for line in rep.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].endswith("%"):
            dso = " ".join(parts[1:])
            dso = "[JIT] numba kernels" if dso.startswith("[JIT]") else dso
            shares[dso] = round(shares.get(dso, 0.0) + float(parts[0][:-1]), 1)
    return dict(sorted(shares.items(), key=lambda kv: -kv[1])[:8])


def profile_numba(args, size: int) -> dict:
    img, t_final, n_contrib = tiles_numba.forward(*args, size, size)
    g_img = np.random.default_rng(0).normal(size=img.shape).astype(np.float32)
    zeros = np.zeros_like(t_final)
    f64 = [np.asarray(a, np.float64) for a in (args[0], args[1], args[3])]

    def best(fn, reps=3):
        ts = []
        for _ in range(reps):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
        return round(min(ts) * 1e3, 1)

    fwd = lambda n=None: tiles_numba.forward(*args, size, size, threads=n)  # noqa: E731
    bwd = lambda n=None: tiles_numba.backward(  # noqa: E731
        *args, size, size, t_final, n_contrib, g_img, zeros, threads=n)
    out = {"binning_ms": best(lambda: tiles_numba.bin_gaussians(*f64, args[4], args[5], size, size)),
           "depth_argsort_ms": best(lambda: np.argsort(args[4], kind="stable"))}
    for n in sorted({1, tiles_numba.worker_count()}):
        out[f"forward_ms_{n}_threads"] = best(lambda: fwd(n))
        out[f"backward_ms_{n}_threads"] = best(lambda: bwd(n))
    # perf on one thread: the shares are not blurred by idle workers
    out["perf_forward_1_thread"] = perf_breakdown(lambda: fwd(1))
    out["perf_backward_1_thread"] = perf_breakdown(lambda: bwd(1))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="200 px / 50k only, 1 rep (smoke run; writes nothing)")
    ap.add_argument("--no-xla-large", action="store_true", help="skip XLA at 800 px (tens of seconds per call)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "splat_raster.json"))
    a = ap.parse_args()
    configs = CONFIGS[:1] if a.quick else CONFIGS
    reps = 1 if a.quick else a.reps
    result = {"machine": {"cpu": cpu_model(), "cores": os.cpu_count(),
                          "worker_threads": tiles_numba.worker_count(), "loadavg_start": os.getloadavg()},
              "versions": {"numba": numba.__version__, "jax": jax.__version__}, "frames_per_config": 2,
              "reps": reps, "configs": []}
    try:
        import warp

        result["versions"]["warp"] = warp.__version__
        import splat_alt_warp as alt_warp
    except Exception as e:  # noqa: BLE001 - a candidate that cannot load is a result too
        alt_warp = None
        result["warp_error"] = repr(e)
    for size, n in configs:
        frames = [lego_scene(n, size, view) for view in range(2)]
        cands = [host_candidate("numba", tiles_numba, frames, size), numba_jax_candidate(frames, size)]
        if alt_warp is not None:
            cands.append(host_candidate("warp", alt_warp, frames, size))
        xla = None if (a.no_xla_large and size > 200) else xla_candidate(frames, size)
        if isinstance(xla, Candidate):
            cands.append(xla)
        entry = {"size": size, "n_gaussians": n, "scene_view0": scene_stats(frames[0], size),
                 "timings": time_candidates(cands, len(frames), reps)}
        if xla is not None:
            entry["xla_budget"] = xla.budget if isinstance(xla, Candidate) else xla
        print(json.dumps({"size": size, "n": n, **entry["timings"]}), flush=True)
        result["configs"].append(entry)
    size, n = configs[-1]
    result["profile_numba"] = {"size": size, "n_gaussians": n, **profile_numba(lego_scene(n, size, 0), size)}
    result["machine"]["loadavg_end"] = os.getloadavg()
    result["provenance"] = provenance()
    print(json.dumps(result["profile_numba"], indent=1))
    if not a.quick:
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(result, indent=1) + "\n")
        print("wrote", a.out)


if __name__ == "__main__":
    main()
