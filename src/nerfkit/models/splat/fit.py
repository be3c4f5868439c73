"""Gaussians fitted to posed images without the command line (tests, benchmarks): the loop that drives
train.ViewStep, one view per step, over a budget of steps or minutes.

    params, log = train_splats(images, poses, cameras, background, SplatConfig(), minutes=10)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import densify as classic
from nerfkit.models.splat.gaussians import PARAM_NAMES, intrinsics_of
from nerfkit.models.splat.optim import init_state, make_optimizers
from nerfkit.models.splat.train import SplatConfig, ViewStep, initial_params
from nerfkit.rays.correction import camera_extent


def train_splats(train_images, poses, cameras, background=(1.0, 1.0, 1.0), cfg: SplatConfig = SplatConfig(), *,
                 minutes: float | None = None, steps: int | None = None, init: dict | None = None,
                 log: Callable[[str], None] | None = None, callback: Callable | None = None,
                 callback_every_s: float | None = None) -> tuple[dict, list[tuple[int, float, float]]]:
    """Fit Gaussians to posed images.

    Args:
      train_images [V, H, W, 3] float in [0, 1]; poses [V, 4, 4] camera-to-world (OpenGL, nerfkit's
      normalised frame); cameras: V pinhole Cameras of one size (H, W); background [3].
      cfg: SplatConfig. minutes / steps: budget of training time (compilation included, callbacks
      excluded) and/or steps; at least one. init: initial Gaussians (gaussians.init_from_points), else
      random in the box. log: called with a progress line every ~10 s.
      callback(step, elapsed_s, params, active): called every callback_every_s seconds of training
      time (and at the end); its own time is not counted.

    Returns (params: numpy dict of the active Gaussians, log: [(step, elapsed_s, photometric loss)]
    every cfg.log_every steps).
    """
    width, height = _image_size(minutes, steps, cameras)
    budget = None if minutes is None else 60.0 * minutes
    extent = camera_extent(poses)
    params, active, opts, opt_state, stats = _initial_state(cfg, init, extent)
    state = {"params": params, "opt_state": opt_state, "aux": {"active": active, **stats}}
    images, poses = jnp.asarray(train_images, jnp.float32), jnp.asarray(poses, jnp.float32)
    intrinsics = jnp.asarray([intrinsics_of(c) for c in cameras], jnp.float32)
    view_step = ViewStep(cfg, opts, width, height, background, extent)
    records, losses = [], []
    clock, step, next_cb, next_log, last_cb = _Clock(time.perf_counter()), 0, callback_every_s, 10.0, -1
    while True:
        elapsed = clock.elapsed()
        progress = max(step / steps if steps else 0.0, elapsed / budget if budget else 0.0)
        if callback and next_cb is not None and elapsed >= next_cb:
            clock.call_paused(callback, step, elapsed, state["params"], state["aux"]["active"])
            next_cb += callback_every_s
            last_cb = step
        if progress >= 1.0:
            break
        state, metrics = view_step(state, step, progress, images, poses, intrinsics)
        step += 1
        losses.append(metrics["loss"])
        if step % cfg.log_every == 0:
            records.append((step, clock.elapsed(), _mean_loss(losses)))
            losses = []
        if log and elapsed >= next_log:
            log(f"step {step}  {elapsed:.0f} s  loss {records[-1][2] if records else float(metrics['loss']):.4f}  "
                f"active {int(metrics['gaussians'])}")
            next_log += 10.0
    if losses:  # the last partial logging interval
        records.append((step, clock.elapsed(), _mean_loss(losses)))
    active = state["aux"]["active"]
    if callback and last_cb != step:
        callback(step, clock.elapsed(), state["params"], active)
    return {k: np.asarray(state["params"][k])[active] for k in PARAM_NAMES}, records


def _image_size(minutes: float | None, steps: int | None, cameras) -> tuple[int, int]:
    """(width, height) shared by all cameras; ValueError without a budget or for cameras of several sizes."""
    if minutes is None and steps is None:
        raise ValueError("train_splats needs minutes= or steps=")
    sizes = {(c.width, c.height) for c in cameras}
    if len(sizes) != 1:
        raise ValueError(f"train_splats needs cameras of one size, got {sorted(sizes)}")
    return sizes.pop()


def _initial_state(cfg: SplatConfig, init: dict | None, extent: float):
    """(params on the device, active mask [capacity], the Adam optimisers, their state, zeroed classic
    statistics) at the start of a run (initial_params; optim.make_optimizers scaled by the scene extent)."""
    p0, active = initial_params(cfg, init)
    params = {k: jnp.asarray(v) for k, v in p0.items()}
    opts = make_optimizers(cfg.lrs, extent, corrections=cfg.corrections)
    return params, active, opts, init_state(opts, params), classic.zero_stats(cfg.capacity)


def _mean_loss(losses: list) -> float:
    """The mean of the logged steps' photometric losses (device scalars)."""
    return float(np.mean([float(x) for x in losses]))


@dataclass
class _Clock:
    """Training time: wall time since t0, less the time spent in callbacks (call_paused)."""

    t0: float
    paused: float = 0.0

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0 - self.paused

    def call_paused(self, fn, *args) -> None:
        """fn(*args), its time not counted as training time."""
        c0 = time.perf_counter()
        fn(*args)
        self.paused += time.perf_counter() - c0
