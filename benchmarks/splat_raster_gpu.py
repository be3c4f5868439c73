"""The splat rasteriser backends on the machine's default JAX device: the pallas kernels (Triton on a GPU)
against the numba host kernels, image for image, and their times; "pallas_s1" is the pallas kernels with the
backward unsegmented (one program per tile, as if rasterize_pallas.segment_count gave 1), to time what the
segments give at small images.

    python benchmarks/splat_raster_gpu.py [--configs 200:50000 800:50000 800:200000] [--reps 5]
                                          [--out benchmarks/results/splat_raster_gpu.json]

Scenes: splat_raster.py's lego-like random Gaussians, projected with the lego camera. Per (size, N) and
backend, under jax.jit: the forward (image + alpha), and the gradient of a loss through it (forward +
backward: what a training step pays), timed after a compile, best and median of --reps; the pallas image
is compared with numba's (max absolute difference: both implement reference.py). A backend that fails (a
kernel that does not compile on the device) is recorded with its error and the script goes on. Off a GPU
the pallas kernels run interpreted: the figures then only check the script (use --configs 64:2000).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from provenance import provenance
from splat_raster import lego_scene

from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.rasterize_pallas import rasterize_pallas


def _timed(fn, args, reps: int) -> tuple[float, float, object]:
    """(compile + first call s, [best, median] ms over reps, last output)."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        times.append(1e3 * (time.perf_counter() - t0))
    return first, [round(min(times), 3), round(float(np.median(times)), 3)], out


def _raster(name: str, size: int):
    """The rasteriser `name` at size x size: a backend, or "pallas_s1" (pallas, one backward segment per tile)."""
    if name == "pallas_s1":
        return lambda m, q, c, o, d, r, bg: rasterize_pallas(m, q, c, o, d, r, bg, size, size, segments=1)
    return lambda m, q, c, o, d, r, bg: rasterize(m, q, c, o, d, r, bg, size, size, backend=name)


def measure(size: int, n: int, reps: int) -> dict:
    scene = tuple(jnp.asarray(a) for a in lego_scene(n, size, 0))
    target = jnp.asarray(np.random.default_rng(1).uniform(0, 1, (size, size, 3)), jnp.float32)
    row = {"size": size, "gaussians": n, "visible": int((scene[5] > 0).sum())}
    images = {}
    for name in ("pallas", "pallas_s1", "numba"):
        raster = _raster(name, size)
        fwd = jax.jit(raster)

        def loss(m, q, c, o, bg, d, r, raster=raster):
            image, alpha = raster(m, q, c, o, d, r, bg)
            return jnp.mean((image - target) ** 2) + 0.1 * jnp.mean(alpha)

        grad = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 4)))
        try:
            first, fwd_ms, (image, _) = _timed(fwd, scene, reps)
            gfirst, grad_ms, grads = _timed(grad, (*scene[:4], scene[6], scene[4], scene[5]), reps)
        except Exception as e:  # a kernel that does not compile on this device: record why, go on
            row[name] = {"error": f"{type(e).__name__}: {str(e)[:4000]}"}
            print(f"{size}px {n} Gaussians, {name}: FAILED: {type(e).__name__}: {str(e)[:2000]}", flush=True)
            continue
        images[name] = np.asarray(image)
        row[name] = {"forward_ms_best_median": fwd_ms, "forward_plus_backward_ms_best_median": grad_ms,
                     "first_call_s": round(first, 2), "grad_first_call_s": round(gfirst, 2),
                     "grad_norms": [float(jnp.linalg.norm(g)) for g in grads]}
        print(f"{size}px {n} Gaussians, {name}: forward {fwd_ms[0]:.2f} ms, forward + backward {grad_ms[0]:.2f} ms "
              f"(best of {reps}; compile + first {first:.1f} s / {gfirst:.1f} s)", flush=True)
    if "pallas" in images and "numba" in images:
        row["max_abs_image_difference"] = float(np.abs(images["pallas"] - images["numba"]).max())
        print(f"  pallas vs numba image: max |difference| {row['max_abs_image_difference']:.2e}", flush=True)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--configs", nargs="+", default=["200:50000", "800:50000", "800:200000"])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results" / "splat_raster_gpu.json")
    a = ap.parse_args()
    dev = jax.devices()[0]
    rows = [measure(int(s), int(n), a.reps) for s, n in (c.split(":") for c in a.configs)]
    result = {"what": "splat rasteriser backends on JAX's default device (pallas vs numba), jitted, ms per frame",
              "device": {"platform": dev.platform, "kind": getattr(dev, "device_kind", str(dev))},
              "pallas_interpreted": jax.default_backend() != "gpu", "rows": rows, "provenance": provenance()}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
