"""Where one splat training step's time goes, on a trained run's Gaussians (compiled, median of 15).

    python benchmarks/splat_step_profile.py RUN [--view 0]

Times, at the run's image size with the run's Gaussians seen from training view `--view`:
the whole jitted step (train.make_step: render, L1 + D-SSIM, gradients, Adam, classic statistics), and its
parts alone: projection + SH colour (forward, and forward + gradient), the tile rasteriser (forward, and
forward + loss + gradient: the numba kernels through jax.pure_callback), the photometric loss's gradient,
and the Adam update. Writes benchmarks/results/splat_step_profile.json.
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

from nerfkit.models.splat import train as T
from nerfkit.models.splat.losses import photometric_loss
from nerfkit.models.splat.gaussians import (
    PARAM_NAMES,
    all_sh,
    band_mask,
    intrinsics_of,
    splat_inputs,
)
from nerfkit.models.splat.optim import adam_step, init_state, make_optimizers
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.rays.cameras import Camera
from nerfkit.run.folder import RunFolder

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, reps: int = 15) -> dict:
    jax.block_until_ready(fn())  # compile
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        ts.append(time.perf_counter() - t0)
    return {"median_ms": round(1e3 * float(np.median(ts)), 1), "min_ms": round(1e3 * min(ts), 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--view", type=int, default=0)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results" / "splat_step_profile.json")
    a = ap.parse_args()
    run = RunFolder(a.run).load()
    p = {k: jnp.asarray(v) for k, v in run.params.items() if k in PARAM_NAMES}
    n = int(p["means"].shape[0])
    cam = Camera.from_json(run.scene["camera"])
    w, h = cam.width, cam.height
    c2w = jnp.asarray(np.asarray(run.scene["train_poses"][a.view], np.float32))
    intr = jnp.asarray(intrinsics_of(cam), jnp.float32)
    target, bg = jnp.full((h, w, 3), 0.5, jnp.float32), jnp.ones(3, jnp.float32)
    cfg = T.SplatConfig(capacity=n, strategy="classic")
    opts = make_optimizers(cfg.lrs, 4.0)
    state, stats, active = init_state(opts, p), T.classic.zero_stats(n), jnp.ones(n, bool)
    step = T.make_step(cfg, opts, w, h)
    data = (target[None], c2w[None], intr[None], bg)

    def inputs(q):
        return splat_inputs(q, c2w, (intr[0], intr[1], intr[2], intr[3]), w, h, all_sh(q) * band_mask(3))

    proj, colors, opac = jax.jit(inputs)(p)

    def project_sum(q):
        pr, col, op = inputs(q)
        return jnp.sum(pr["means2d"]) + jnp.sum(pr["conics"]) + jnp.sum(col) + jnp.sum(op)

    def raster(m, q, c, o):
        return rasterize(m, q, c, o, proj["depths"], proj["radii"], bg, w, h)[0]

    raster_loss = jax.jit(jax.value_and_grad(lambda *x: photometric_loss(raster(*x), target), argnums=(0, 1, 2, 3)))
    project_fwd, project_grad, raster_fwd = jax.jit(inputs), jax.jit(jax.grad(project_sum)), jax.jit(raster)
    loss_grad = jax.jit(jax.grad(lambda x: photometric_loss(x, target)))
    adam = jax.jit(lambda s, g, q: adam_step(opts, s, g, q, 1e-4))
    grads = project_grad(p)
    args = (proj["means2d"], proj["conics"], colors, opac)
    parts = {
        "whole_step": timed(lambda: step(p, state, stats, active, *data, 0, jax.random.PRNGKey(0), 1e-4, 3)),
        "project_sh_forward": timed(lambda: project_fwd(p)),
        "project_sh_forward_grad": timed(lambda: project_grad(p)),
        "rasterise_forward": timed(lambda: raster_fwd(*args)),
        "rasterise_forward_loss_grad": timed(lambda: raster_loss(*args)),
        "loss_grad": timed(lambda: loss_grad(target * 0.9)),
        "adam": timed(lambda: adam(state, grads, p)),
    }
    for k, v in parts.items():
        print(f"{k}: {v['median_ms']} ms (min {v['min_ms']})")
    out = {"what": "one splat training step and its parts, compiled", "provenance": provenance(), "run": str(a.run),
           "gaussians": n, "width": w, "height": h, "view": a.view, "parts": parts}
    a.results.parent.mkdir(parents=True, exist_ok=True)
    a.results.write_text(json.dumps(out, indent=1))
    print(f"wrote {a.results}")


if __name__ == "__main__":
    main()
