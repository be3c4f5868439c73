"""Standalone 3DGS training: one image per step, a jit-compiled step, density control on the host.

    params, log = train_splats(images, poses, cameras, background, SplatConfig(), minutes=10)

One step (compiled once for the run; the SH degree is a traced band mask, the means' learning
rate a traced scalar, so nothing recompiles when they change):

    render training view k (project.py + SH + the numba tile rasteriser), with inactive slots culled
    L = (1 - 0.2) L1 + 0.2 (1 - SSIM)  [+ MCMC's opacity and scale regularisers]
    Adam per parameter group (optim.py)  [+ MCMC position noise | classic gradient statistics]

Coarse to fine: while progress t < coarse_until, a step renders and scores the view at half
resolution (half_resolution: 2x2 pixels averaged, intrinsics halved; a second compiled step,
with the screen dilation a quarter in half-pixels^2, the photos' footprint: project.py), a
quarter of the rasteriser's work, so the early, coarse fitting takes more steps.

Views are visited in a fresh random order every epoch (3DGS draws one camera per step). The SH
degree rises by one every `sh_interval` steps up to 3. Every `control_every` steps the host runs
the density control (mcmc.py: relocation and growth; densify.py: clone/split/prune) on numpy
copies and resets the Adam moments of the slots it wrote.

Progress t in [0, 1] (for the means' learning-rate decay and the density-control windows) is
the larger of step / steps and elapsed / budget, whichever limits are given.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.metrics import psnr, ssim
from nerfkit.models.splat import densify as classic
from nerfkit.models.splat import mcmc
from nerfkit.models.splat.losses import PIXEL_LOSSES, SSIM_LAMBDA, photometric_loss
from nerfkit.models.splat.model import (
    PARAM_NAMES,
    all_sh,
    band_mask,
    init_random,
    intrinsics_of,
    render,
    splat_inputs,
)
from nerfkit.models.splat.optim import (
    LearningRates,
    adam_step,
    init_state,
    make_optimizers,
    means_lr,
    reset_rows,
    scene_extent,
)
from nerfkit.models.splat.project import LOWPASS_DILATION
from nerfkit.models.splat.rasterize import rasterize


@dataclass(frozen=True)
class SplatConfig:
    """Settings of train_splats (defaults: the CPU lego choices measured in benchmarks/splat_lego.py)."""

    capacity: int = 50_000  # fixed number of Gaussian slots (static shapes)
    init_count: int | None = None  # slots active at the start (None: all); MCMC grows to capacity
    strategy: str = "mcmc"  # "mcmc", "classic" or "none"
    lrs: LearningRates = field(default_factory=LearningRates)
    ssim_lambda: float = SSIM_LAMBDA
    pixel_loss: str = "l1"  # losses.PIXEL_LOSSES: "l1" (3DGS) or "rmse"
    sh_degree: int = 3
    sh_interval: int = 500  # steps per SH band (3DGS: 1000 of 30k; a CPU run is ~5k steps)
    control_every: int = 100  # steps between density-control rounds
    control_from: int = 500  # first step with density control
    control_until: float = 0.8  # progress after which density control stops (MCMC: 25k of 30k)
    coarse_until: float = 0.0  # progress before which views train at half resolution (coarse to fine; 0: never)
    opacity_reg: float = mcmc.OPACITY_REG
    scale_reg: float = mcmc.SCALE_REG
    noise_lr: float = mcmc.NOISE_LR
    grow_rate: float = 0.05
    classic: classic.ClassicSchedule = field(default_factory=classic.ClassicSchedule)
    init_box: float = 1.5  # random init in [-box, box]^3 when no points are given
    init_opacity: float = 0.1
    init_scale: float = 1.0  # initial scales = this x the nearest-neighbour distance (gsplat's init_scale)
    seed: int = 0
    backend: str = "auto"
    log_every: int = 10

    def __post_init__(self):
        if self.strategy not in ("mcmc", "classic", "none"):
            raise ValueError(f"strategy must be mcmc, classic or none, got {self.strategy!r}")
        if self.pixel_loss not in PIXEL_LOSSES:
            raise ValueError(f"pixel_loss must be one of {sorted(PIXEL_LOSSES)}, got {self.pixel_loss!r}")
        if not 0 <= self.sh_degree <= 3:
            raise ValueError(f"sh_degree must be 0..3, got {self.sh_degree}")


def initial_params(cfg: SplatConfig, init: dict | None = None) -> tuple[dict, np.ndarray]:
    """(params with cfg.capacity slots, active mask [capacity]) from `init` (e.g. model.init_from_points)
    or random points in the box. More init Gaussians than slots: a random subset; fewer: the rest of
    the slots are filled with random ones (inactive when the init is given, else all active)."""
    rng = np.random.default_rng(cfg.seed)
    n_active = cfg.capacity if cfg.init_count is None else min(cfg.init_count, cfg.capacity)
    if init is None:
        params = init_random(cfg.capacity, cfg.init_box, cfg.seed, cfg.init_opacity)
    else:
        n0 = len(init["means"])
        keep = rng.permutation(n0)[: cfg.capacity] if n0 > cfg.capacity else np.arange(n0)
        pad = init_random(cfg.capacity - len(keep), cfg.init_box, cfg.seed, cfg.init_opacity)
        params = {k: np.concatenate([np.asarray(init[k], np.float32)[keep], pad[k]]) for k in PARAM_NAMES}
        n_active = min(n_active, len(keep))
    params["log_scales"] = params["log_scales"] + np.float32(np.log(cfg.init_scale))
    active = np.zeros(cfg.capacity, bool)
    active[:n_active] = True
    return params, active


def _loss_fn(params, offset, image, c2w, intr, bg, sh_mask, active, *, cfg, width, height, dilation):
    """Loss of one view and aux (photometric loss, radii); offset [N, 2] zeros: d/d offset = dL/dmeans2d."""
    proj, colors, opac = splat_inputs(params, c2w, (intr[0], intr[1], intr[2], intr[3]), width, height,
                                      all_sh(params) * sh_mask, dilation)
    radii = jnp.where(active, proj["radii"], 0)
    rgb, _ = rasterize(proj["means2d"] + offset, proj["conics"], colors, opac, proj["depths"], radii, bg, width, height,
                       backend=cfg.backend)
    photo = photometric_loss(rgb, image, cfg.ssim_lambda, cfg.pixel_loss)
    loss = photo
    if cfg.strategy == "mcmc":
        loss = loss + mcmc.regularizer(params, cfg.opacity_reg, cfg.scale_reg, active)
    return loss, (photo, radii, jnp.mean((rgb - image) ** 2))


def make_step(cfg: SplatConfig, opts: dict, width: int, height: int, with_health: bool = False, scale: float = 1.0):
    """The jitted training step

        step(params, opt_state, stats, active, images, poses, intrinsics, background, idx, key, lr_means, sh_degree)
          -> params, opt_state, stats, photometric loss [, mse, finite]

    images [V, H, W, 3], poses [V, 4, 4], intrinsics [V, 4] stay on the device; idx picks the view.
    A step whose loss or gradients are not finite changes nothing (finite: False). with_health also
    returns the view's MSE and that flag (what nerfkit's run loop logs). scale: the views' resolution as a
    fraction of the photos' (1/2 in the coarse phase); the screen dilation is LOWPASS_DILATION scale^2, the
    same footprint in the photos' pixels (project.py)."""
    loss_grad = jax.value_and_grad(partial(_loss_fn, cfg=cfg, width=width, height=height,
                                           dilation=LOWPASS_DILATION * scale * scale), argnums=(0, 1), has_aux=True)

    @jax.jit
    def step(params, opt_state, stats, active, images, poses, intrinsics, background, idx, key, lr_means, sh_degree):
        offset = jnp.zeros((params["means"].shape[0], 2), jnp.float32)
        (loss, (photo, radii, mse)), (grads, g_m2d) = loss_grad(params, offset, images[idx], poses[idx],
                                                                intrinsics[idx], background, band_mask(sh_degree),
                                                                active)
        finite = jnp.isfinite(loss)
        for g in jax.tree_util.tree_leaves(grads):
            finite = finite & jnp.all(jnp.isfinite(g))
        new_params, new_opt = adam_step(opts, opt_state, grads, params, lr_means)
        new_stats = stats
        if cfg.strategy == "mcmc":
            noise = mcmc.position_noise(key, new_params, lr_means, cfg.noise_lr)
            new_params = dict(new_params, means=new_params["means"] + jnp.where(active[:, None], noise, 0.0))
        elif cfg.strategy == "classic":
            new_stats = classic.accumulate(stats, g_m2d, radii, width, height)
        keep = partial(jax.tree_util.tree_map, lambda new, old: jnp.where(finite, new, old))
        out = (keep(new_params, params), keep(new_opt, opt_state), keep(new_stats, stats), photo)
        return (*out, mse, finite) if with_health else out

    return step


def half_step(cfg: SplatConfig, opts: dict, width: int, height: int, with_health: bool = False):
    """make_step for views at half of the photos' width x height (coarse to fine: their images and intrinsics
    from half_resolution), with the screen dilation scaled to keep the photos' footprint."""
    return make_step(cfg, opts, width // 2, height // 2, with_health=with_health, scale=0.5)


def half_resolution(images: jnp.ndarray, intrinsics: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The views at half resolution: images [V, H, W, 3] -> [V, H // 2, W // 2, 3], each pixel the mean of a
    2x2 block (an odd last row or column dropped), and their intrinsics [V, 4] (fx, fy, cx, cy) / 2 (pixel
    centres at half-integers: the small pixel j covers the big ones 2j and 2j + 1, centre 2j + 1 = 2 (j + 1/2))."""
    v, h, w, c = images.shape
    small = images[:, : h // 2 * 2, : w // 2 * 2].reshape(v, h // 2, 2, w // 2, 2, c).mean(axis=(2, 4))
    return small, intrinsics / 2.0


def _host(params: dict) -> dict:
    return {k: np.asarray(v) for k, v in params.items()}


def _control(cfg, step, params, opt_state, stats, active, rng, extent, width, opacity_resets):
    """One density-control round on the host; returns (params, opt_state, stats, active)."""
    n = cfg.capacity
    p = _host(params)
    if cfg.strategy == "mcmc":
        p, touched = mcmc.relocate(p, active, rng)
        if not active.all():
            p, active, grown = mcmc.grow(p, active, rng, cfg.grow_rate)
            touched = np.union1d(touched, grown)
    else:
        p, active, touched = classic.densify(p, active, stats, extent, rng, cfg.classic, width, opacity_resets > 0)
        stats = classic.zero_stats(n)
    opt_state = reset_rows(opt_state, touched, n) if len(touched) else opt_state
    return {k: jnp.asarray(v) for k, v in p.items()}, opt_state, stats, active


def host_control(cfg: SplatConfig, step: int, progress: float, params, opt_state, stats, active, rng, extent: float,
                 width: int):
    """What the host does after step `step` (1-based count of steps done) at progress in [0, 1]: a
    density-control round every cfg.control_every steps from cfg.control_from while progress <
    cfg.control_until, and (classic, when classic.reset_every > 0) the opacity reset every reset_every steps
    in that window.
    Returns (params, opt_state, stats, active, what: list of "control" / "reset")."""
    what = []
    window = progress < cfg.control_until
    every = cfg.classic.reset_every if cfg.strategy == "classic" else 0
    reset_now = every > 0 and step % every == 0 and window
    resets = step // every - reset_now if every > 0 else 0  # resets done before this step
    if cfg.strategy != "none" and step >= cfg.control_from and step % cfg.control_every == 0 and window:
        params, opt_state, stats, active = _control(cfg, step, params, opt_state, stats, active, rng, extent, width,
                                                    resets)
        what.append("control")
    if reset_now:
        params = dict(params, opacity=jnp.asarray(classic.reset_opacity(_host(params), cfg.classic.reset_opacity)
                                                  ["opacity"]))
        opt_state = dict(opt_state, opacity=reset_rows(opt_state["opacity"], np.arange(cfg.capacity), cfg.capacity))
        what.append("reset")
    return params, opt_state, stats, active, what


def train_splats(train_images, poses, cameras, background=(1.0, 1.0, 1.0), cfg: SplatConfig = SplatConfig(), *,
                 minutes: float | None = None, steps: int | None = None, init: dict | None = None,
                 log: Callable[[str], None] | None = None, callback: Callable | None = None,
                 callback_every_s: float | None = None) -> tuple[dict, list[tuple[int, float, float]]]:
    """Fit Gaussians to posed images.

    Args:
      train_images [V, H, W, 3] float in [0, 1]; poses [V, 4, 4] camera-to-world (OpenGL, nerfkit's
      normalised frame); cameras: V pinhole Cameras of one size (H, W); background [3].
      cfg: SplatConfig. minutes / steps: budget of training time (compilation included, callbacks
      excluded) and/or steps; at least one. init: initial Gaussians (model.init_from_points), else
      random in the box. log: called with a progress line every ~10 s.
      callback(step, elapsed_s, params, active): called every callback_every_s seconds of training
      time (and at the end); its own time is not counted.

    Returns (params: numpy dict of the active Gaussians, log: [(step, elapsed_s, photometric loss)]
    every cfg.log_every steps).
    """
    width, height = _image_size(minutes, steps, cameras)
    budget = None if minutes is None else 60.0 * minutes
    extent = scene_extent(poses)
    rng, base_key = np.random.default_rng(cfg.seed), jax.random.PRNGKey(cfg.seed)
    params, active, opts, opt_state, stats = _initial_state(cfg, init, extent)
    data = (jnp.asarray(train_images, jnp.float32), jnp.asarray(poses, jnp.float32),
            jnp.asarray([intrinsics_of(c) for c in cameras], jnp.float32), jnp.asarray(background, jnp.float32))
    fine, coarse = _steps(cfg, opts, width, height, data)
    order, records, losses = np.zeros(0, int), [], []
    clock, step, next_cb, next_log, last_cb = _Clock(time.perf_counter()), 0, callback_every_s, 10.0, -1
    while True:
        elapsed = clock.elapsed()
        progress = max(step / steps if steps else 0.0, elapsed / budget if budget else 0.0)
        if callback and next_cb is not None and elapsed >= next_cb:
            clock.call_paused(callback, step, elapsed, params, active)
            next_cb += callback_every_s
            last_cb = step
        if progress >= 1.0:
            break
        if len(order) == 0:
            order = rng.permutation(len(train_images))
        idx, order = int(order[0]), order[1:]
        deg = min(cfg.sh_degree, step // cfg.sh_interval)
        fn, views, w_now = coarse if progress < cfg.coarse_until else fine
        params, opt_state, stats, photo = fn(params, opt_state, stats, jnp.asarray(active), *views, idx,
                                             jax.random.fold_in(base_key, step), means_lr(progress, extent, cfg.lrs), deg)
        step += 1
        losses.append(photo)
        if step % cfg.log_every == 0:
            records.append((step, clock.elapsed(), _mean_loss(losses)))
            losses = []
        params, opt_state, stats, active, _ = host_control(cfg, step, progress, params, opt_state, stats, active, rng,
                                                          extent, w_now)
        if log and elapsed >= next_log:
            log(f"step {step}  {elapsed:.0f} s  loss {records[-1][2] if records else float(photo):.4f}  "
                f"active {int(active.sum())}")
            next_log += 10.0
    if losses:  # the last partial logging interval
        records.append((step, clock.elapsed(), _mean_loss(losses)))
    if callback and last_cb != step:
        callback(step, clock.elapsed(), params, active)
    return {k: np.asarray(v)[active] for k, v in params.items()}, records


def _steps(cfg: SplatConfig, opts: dict, width: int, height: int, data: tuple):
    """((step, views, width) at full resolution, the same at half resolution or None without a coarse phase):
    views = (images, poses, intrinsics, background) on the device."""
    fine = (make_step(cfg, opts, width, height), data, width)
    if cfg.coarse_until <= 0:
        return fine, None
    small, small_intr = half_resolution(data[0], data[2])
    return fine, (half_step(cfg, opts, width, height), (small, data[1], small_intr, data[3]), width // 2)


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
    opts = make_optimizers(cfg.lrs, extent)
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


def evaluate(params: dict, images, poses, cameras, background=(1.0, 1.0, 1.0), sh_degree: int = 3,
             backend: str = "auto") -> dict:
    """Render every camera and score it: {"psnr": [V], "ssim": [V], "psnr_mean", "ssim_mean"} (nerfkit.core.metrics)."""
    ps, ss = [], []
    for k, cam in enumerate(cameras):
        rgb = render(params, poses[k], cam, background, sh_degree, backend, depth=False)["rgb"]
        target = np.asarray(images[k])[: cam.height, : cam.width]
        ps.append(psnr(np.clip(rgb, 0, 1), target))
        ss.append(ssim(np.clip(rgb, 0, 1), target))
    return {"psnr": ps, "ssim": ss, "psnr_mean": float(np.mean(ps)), "ssim_mean": float(np.mean(ss))}
