"""Bake, then fine-tune: optimise the baked values against the training images (SNeRG, MERF).

Sampling the field at cell vertices loses detail twice: trilinear interpolation of a coarser
grid blurs what the hash grid resolved, and a few SH bands cannot hold all of the field's
view dependence. Both are fixed where it matters, in image space: the baked log-densities
a [K, S, S, S] and SH coefficients [K, S, S, S, C] are the parameters of the reference
renderer (model.BakedModel.render_packed: the same sample positions, look-up and compositing
that `nerfkit eval --baked` and the browser use), and Adam minimises

    L = mean_r || C_baked(r) - C_image(r) ||^2

over random batches of training pixels for a wall-clock budget, the learning rate decaying
exponentially from LR to LR / 10 with the elapsed fraction of the budget. Only bricks that
are stored get gradients; the brick set does not change.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax
from tqdm.auto import tqdm

from nerfkit.core.metrics import mse_to_psnr
from nerfkit.data.loader import load_frames, read_capture, scene_cameras
from nerfkit.models.baked.format import Baked
from nerfkit.models.baked.model import BakedModel
from nerfkit.rays.cameras import (
    draw_pixels,
    ray_table,
    rotate_directions,
    table_directions,
)
from nerfkit.run.folder import RunFolder

LR = 3e-2
BATCH_RAYS = 4096
SAMPLES_PER_RAY = 96  # packed samples in stored bricks, per ray
LIVE_PER_RAY = 32  # of which still seen (T >= 1e-4); rays needing more are rendered but not scored


def _training_capture(run):
    d = run.cfg.data
    return read_capture(RunFolder(run.run_dir).data_dir(None), d.train_split, d.format, d.masks, d.holdout_every)


def training_frames(run):
    """The run's training images (its split, resolution and background), posed as the run sees them (its
    refined poses where it learned them: TrainedRun.seen_from)."""
    d = run.cfg.data
    data = load_frames(_training_capture(run), d.train_split, downscale=d.downscale, target_width=d.target_width,
                       background=d.background, progress=False, undistort=d.undistort)
    return dataclasses.replace(data, poses=run.seen_from(d.train_split, data.poses))


def training_poses(run) -> np.ndarray:
    """The run's training poses c2w [N, 4, 4] (normalised frame, refined where the run learned them), without
    reading the images."""
    d = run.cfg.data
    return run.seen_from(d.train_split, scene_cameras(_training_capture(run), d.train_split, d.downscale,
                                                      d.target_width, d.undistort).poses)


def make_step(model: BakedModel, data, optimizer, batch: int, budget: int, live_budget: int | None, seed: int = 0):
    """A jitted step(state, step, lr, aux, index) -> (state, mse, rays scored) on `batch` random training
    pixels: params <- params - lr * direction, the direction from `optimizer` (Adam's)."""
    table = {k: jnp.asarray(v) for k, v in ray_table(data.cameras).items()}
    images, poses = jnp.asarray(data.images), jnp.asarray(data.poses)
    sizes = jnp.asarray([(c.height, c.width) for c in data.cameras])  # each image's own (multiscale data pads)
    base = jax.random.PRNGKey(seed)

    def step_fn(state, step, lr, aux, index):
        img, i, j = draw_pixels(jax.random.fold_in(base, step), batch, sizes)
        o, d = rotate_directions(poses[img], table_directions(table, img, i, j))
        target = images[img, i, j]

        def loss_fn(p):
            out = model.render_packed({"field": {**p, "index": index}}, aux, o, d, budget, live_budget)
            mask = out["complete"].astype(jnp.float32)
            mse = jnp.sum(mask[:, None] * (out["rgb"] - target) ** 2) / (3.0 * jnp.maximum(jnp.sum(mask), 1.0))
            return mse, jnp.sum(mask)

        (mse, scored), grads = jax.value_and_grad(loss_fn, has_aux=True)(state["params"])
        direction, opt_state = optimizer.update(grads, state["opt"], state["params"])
        params = jax.tree_util.tree_map(lambda p, u: p - lr * u, state["params"], direction)
        return {"params": params, "opt": opt_state}, mse, scored

    jitted = jax.jit(step_fn, donate_argnums=(0,))
    return lambda state, step, lr, aux, index: jitted(state, step, jnp.float32(lr), aux, index)


def finetune(run, baked: Baked, minutes: float, progress: bool = True, log=print,
             max_steps: int | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Optimised (log-density [K, S, S, S], coefficients [K, S, S, S, C]) float32, and a summary
    (steps, seconds, first and last batch PSNR), from `baked` holding float (not yet quantised) values.
    max_steps: stop after that many steps instead (the learning rate then decays over the steps)."""
    model = BakedModel(baked)
    aux = model.occupancy(baked.index)
    params = {"density": jnp.asarray(baked.density, jnp.float32), "sh": jnp.asarray(baked.sh, jnp.float32)}
    index = jnp.asarray(baked.index)
    data = training_frames(run)
    optimizer = optax.scale_by_adam()  # Adam's direction; the step applies the decaying learning rate
    step = make_step(model, data, optimizer, BATCH_RAYS, BATCH_RAYS * SAMPLES_PER_RAY, BATCH_RAYS * LIVE_PER_RAY)
    state = {"params": params, "opt": optimizer.init(params)}

    budget_s = 60.0 * minutes
    t0 = time.perf_counter()
    first = last = None
    k = 0
    bar = tqdm(total=int(budget_s), desc="fine-tune", unit="s", disable=not progress)
    while True:
        elapsed = time.perf_counter() - t0
        done = k / max_steps if max_steps else elapsed / budget_s
        if done >= 1.0 and k > 0:
            break
        lr = LR * 0.1 ** done
        state, mse, scored = step(state, k, lr, aux, index)
        mse = float(mse)
        p = float(mse_to_psnr(mse))
        first = p if first is None else first
        last = p if last is None else 0.9 * last + 0.1 * p
        k += 1
        bar.n = min(int(time.perf_counter() - t0), int(budget_s))
        bar.set_postfix(step=k, psnr=f"{last:.2f}", rays=int(scored))
    bar.close()
    seconds = time.perf_counter() - t0
    log(f"fine-tuned the baked values for {k} steps ({seconds:.0f} s): batch PSNR {first:.2f} -> {last:.2f} dB")
    out = state["params"]
    return (np.asarray(out["density"]), np.asarray(out["sh"]),
            {"steps": k, "seconds": seconds, "psnr_first": first, "psnr_last": last})
