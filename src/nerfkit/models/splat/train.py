"""3DGS training, step by step: one image per step, a jit-compiled step, density control on the host
(ViewStep; fit.train_splats drives it without the command line, SplatModel.make_train_step with it).

One step (compiled once for the run; the SH degree is a traced band mask, the means' learning
rate a traced scalar, so nothing recompiles when they change):

    render training view k (project.py + SH + the numba tile rasteriser), with inactive slots culled
    L = (1 - 0.2) L1 + 0.2 (1 - SSIM)  [+ MCMC's opacity and scale regularisers] [+ W L_n] [+ W_d L_d, surface.py]
    Adam per parameter group (optim.py)  [+ MCMC position noise | classic gradient statistics]

Coarse to fine: while progress t < coarse_until, a step renders and scores the view at half
resolution (half_resolution: 2x2 pixels averaged, intrinsics halved; a second compiled step,
with the screen dilation a quarter in half-pixels^2, the photos' footprint: project.py), a
quarter of the rasteriser's work, so the early, coarse fitting takes more steps. Likewise the
surface terms (normal consistency W L_n, depth distortion W_d L_d) are on from t = normal_consistency_from
(2DGS starts them after a warm-up): before that a step compiled without them (nor their extra channels) runs.

Views are visited in a fresh random order every epoch (3DGS draws one camera per step). The SH
degree rises by one every `sh_interval` steps up to 3. Every `window.every` steps the host runs
the density control (mcmc.py: relocation and growth; densify.py: clone/split/prune) on numpy
copies and resets the Adam moments of the slots it wrote.

Progress t in [0, 1] (for the means' learning-rate decay, the density-control windows and the
phases above) is the share of the budget used: the larger of step / steps and elapsed / budget,
whichever limits are given.
"""

from __future__ import annotations

from typing import Any
from dataclasses import dataclass, field, replace
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.config import SplatSettings
from nerfkit.models.splat import densify as classic
from nerfkit.models.splat.losses import PIXEL_LOSSES, on_random_background, photometric_loss
from nerfkit.models.splat.gaussians import PARAM_NAMES, all_sh, band_mask, init_random, splat_inputs
from nerfkit.models.splat.optim import LearningRates, adam_step, colour_lr, means_lr, pose_lr, reset_rows
from nerfkit.models.splat.pose_solve import solve_corrections, solve_due
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.strategy import strategy_named
from nerfkit.models.splat.surface import depth_distortion, normal_consistency, with_surface_channels
from nerfkit.rays.correction import COLOR_FORMS, corrected_composite, corrected_pose


_USER = SplatSettings()  # the user-facing defaults


@dataclass(frozen=True)
class SplatConfig:
    """The whole of a splat run's settings (the step's, the schedule's and the strategy's). The ones a user sets
    take their defaults from the one place they are declared, core/config.SplatSettings (--preset splat's flags;
    method.splat_config copies a run's values in); the rest are the method's own."""

    capacity: int = _USER.capacity  # fixed number of Gaussian slots (static shapes)
    init_count: int | None = None  # slots active at the start (None: all); MCMC grows to capacity
    strategy: Any = _USER.strategy  # a strategy.py object (MCMC, Classic, NoControl), or its name: its defaults
    lrs: LearningRates = field(default_factory=LearningRates)
    ssim_lambda: float = _USER.ssim_lambda
    pixel_loss: str = _USER.pixel_loss  # losses.PIXEL_LOSSES: "l1" (3DGS) or "rmse"
    sh_degree: int = _USER.sh_degree
    sh_interval: int = _USER.sh_interval  # steps per SH band (3DGS: 1000 of 30k; a CPU run is ~5k steps)
    sh_start: int = 0  # the SH degree at step 0 (a run that starts from trained Gaussians: their file's degree)
    coarse_until: float = 0.0  # progress before which views train at half resolution (coarse to fine; 0: never)
    init_box: float = 1.5  # random init in [-box, box]^3 when no points are given
    init_opacity: float = 0.1
    init_scale: float = 1.0  # initial scales = this x the nearest-neighbour distance (gsplat's init_scale)
    seed: int = 0
    backend: str = _USER.backend
    appearance: bool = False  # a colour transform per training photo (rays/correction.py)
    colour_transform: str = "gain"  # the entries of those transforms learned (correction.COLOR_FORMS)
    pose_refine: bool = False  # a pose correction per training photo (rays/correction.py)
    pose_solves: int = 0  # Levenberg-Marquardt solves of the pose corrections per run or round (pose_solve.py)
    pose_solve_share: float = 1.0  # the share of each solve's step the corrections take (pose_solve.py: a)
    random_background: bool = False  # RGBA views train on a random background colour per step (_loss_fn)
    normal_consistency: float = 0.0  # weight of surface.normal_consistency in the loss (0: off)
    normal_consistency_from: float = 0.0  # progress from which the surface terms are on (before: steps without)
    depth_distortion: float = 0.0  # weight of surface.depth_distortion in the loss (0: off)
    screen_dilation: float = _USER.screen_dilation  # px^2 added to each footprint's covariance (project.py)
    n_views: int = 0  # training photos (the corrections' leading axis)
    log_every: int = 10

    @property
    def corrections(self) -> tuple[str, ...]:
        """The per-photo parameter groups this run learns (optim.CORRECTIONS): cam_color, cam_pose."""
        return tuple(k for k, on in (("cam_color", self.appearance), ("cam_pose", self.pose_refine)) if on)

    def __post_init__(self):
        if isinstance(self.strategy, str):
            object.__setattr__(self, "strategy", strategy_named(self.strategy))
        if self.pixel_loss not in PIXEL_LOSSES:
            raise ValueError(f"pixel_loss must be one of {sorted(PIXEL_LOSSES)}, got {self.pixel_loss!r}")
        if not 0 <= self.sh_degree <= 3:
            raise ValueError(f"sh_degree must be 0..3, got {self.sh_degree}")
        if self.colour_transform not in COLOR_FORMS:
            raise ValueError(f"colour_transform must be one of {sorted(COLOR_FORMS)}, got {self.colour_transform!r}")
        if self.corrections and self.n_views < 1:
            raise ValueError("per-photo corrections need n_views, the number of training photos")


def initial_params(cfg: SplatConfig, init: dict | None = None) -> tuple[dict, np.ndarray]:
    """(params with cfg.capacity slots, active mask [capacity]) from `init` (e.g. gaussians.init_from_points)
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
    params.update(correction_params(cfg))
    active = np.zeros(cfg.capacity, bool)
    active[:n_active] = True
    return params, active


def correction_params(cfg: SplatConfig) -> dict:
    """The per-photo corrections at the identity: cam_color [V, 3, 4] and cam_pose [V, 6] zeros (those on)."""
    shapes = {"cam_color": (cfg.n_views, 3, 4), "cam_pose": (cfg.n_views, 6)}
    return {k: np.zeros(shapes[k], np.float32) for k in cfg.corrections}


def _loss_fn(params, offset, image, c2w, intr, bg, sh_mask, active, idx, key, *, cfg, width, height, dilation, extent):
    """Loss of one view (training photo idx) and aux (photometric loss, radii); offset [N, 2] zeros: d/d offset =
    dL/dmeans2d. With per-photo corrections the view is rendered from its corrected pose and its colours are
    transformed by its colour transform (rays/correction.py) before the loss. An RGBA image [H, W, 4] (the photo
    composited on bg, and its alpha) is trained on a random background drawn from key (losses.on_random_background)."""
    if image.shape[-1] == 4:
        image, bg = on_random_background(image, bg, key)
    if "cam_pose" in params:
        c2w = corrected_pose(c2w, params["cam_pose"][idx], extent)
    proj, colors, opac = splat_inputs(params, c2w, (intr[0], intr[1], intr[2], intr[3]), width, height,
                                      all_sh(params) * sh_mask, dilation)
    radii = jnp.where(active, proj["radii"], 0)
    surface = surface_terms(cfg)  # then the Gaussians' normals and planes follow the colour (surface.py)
    channels, bg_in = (with_surface_channels(colors, bg, params, c2w, cfg.depth_distortion > 0) if surface
                       else (colors, bg))
    rendered, alpha = rasterize(proj["means2d"] + offset, proj["conics"], channels, opac, proj["depths"], radii,
                                bg_in, width, height, backend=cfg.backend)
    rgb = rendered[..., :3]
    if "cam_color" in params:
        rgb = corrected_composite(rgb, alpha, bg, params["cam_color"][idx] * COLOR_FORMS[cfg.colour_transform])
    photo = photometric_loss(rgb, image, cfg.ssim_lambda, cfg.pixel_loss)
    loss = photo + cfg.strategy.regularizer(params, active)
    if cfg.normal_consistency > 0:
        loss = loss + cfg.normal_consistency * normal_consistency(rendered[..., 3:], alpha, intr)
    if cfg.depth_distortion > 0:
        loss = loss + cfg.depth_distortion * depth_distortion(rendered[..., 3:], alpha, intr)
    return loss, (photo, radii, jnp.mean((rgb - image) ** 2))


def surface_terms(cfg: SplatConfig) -> bool:
    """Whether cfg trains with a surface term (normal consistency, depth distortion; surface.py)."""
    return cfg.normal_consistency > 0 or cfg.depth_distortion > 0


BACKGROUND_KEY = 0x6B67  # folded into a step's key for its random background (the strategy uses the key itself)


def make_step(cfg: SplatConfig, opts: dict, width: int, height: int, with_health: bool = False, scale: float = 1.0,
              extent: float = 1.0):
    """The jitted training step

        step(params, opt_state, stats, active, images, poses, intrinsics, background, idx, key, lr_means, sh_degree,
             lr_pose=0, lr_color=None) -> params, opt_state, stats, photometric loss [, mse, finite]

    images [V, H, W, 3] (or RGBA [V, H, W, 4]: a random background, _loss_fn), poses [V, 4, 4], intrinsics [V, 4]
    stay on the device; idx picks the view.
    A step whose loss or gradients are not finite changes nothing (finite: False). with_health also
    returns the view's MSE and that flag (what nerfkit's run loop logs). scale: the views' resolution as a
    fraction of the photos' (1/2 in the coarse phase); the screen dilation is cfg.screen_dilation scale^2, the
    same footprint in the photos' pixels (project.py). extent: the unit of the pose corrections' translations.
    lr_pose, lr_color: the rates of the pose corrections and colour transforms this step (optim.pose_lr,
    optim.colour_lr; lr_color None keeps the optimiser's own)."""
    loss_grad = jax.value_and_grad(partial(_loss_fn, cfg=cfg, width=width, height=height, extent=extent,
                                           dilation=cfg.screen_dilation * scale * scale), argnums=(0, 1),
                                   has_aux=True)

    @jax.jit
    def step(params, opt_state, stats, active, images, poses, intrinsics, background, idx, key, lr_means, sh_degree,
             lr_pose=0.0, lr_color=None):
        offset = jnp.zeros((params["means"].shape[0], 2), jnp.float32)
        (loss, (photo, radii, mse)), (grads, g_m2d) = loss_grad(params, offset, images[idx], poses[idx],
                                                                intrinsics[idx], background, band_mask(sh_degree),
                                                                active, idx, jax.random.fold_in(key, BACKGROUND_KEY))
        finite = jnp.isfinite(loss)
        for g in jax.tree_util.tree_leaves(grads):
            finite = finite & jnp.all(jnp.isfinite(g))
        new_params, new_opt = adam_step(opts, opt_state, grads, params, lr_means, lr_pose, lr_color)
        new_params, new_stats = cfg.strategy.after_adam(key, new_params, stats, g_m2d, radii, active, lr_means, width,
                                                        height)
        keep = partial(jax.tree_util.tree_map, lambda new, old: jnp.where(finite, new, old))
        out = (keep(new_params, params), keep(new_opt, opt_state), keep(new_stats, stats), photo)
        return (*out, mse, finite) if with_health else out

    return step


def half_step(cfg: SplatConfig, opts: dict, width: int, height: int, with_health: bool = False, extent: float = 1.0):
    """make_step for views at half of the photos' width x height (coarse to fine: their images and intrinsics
    from half_resolution), with the screen dilation scaled to keep the photos' footprint."""
    return make_step(cfg, opts, width // 2, height // 2, with_health=with_health, scale=0.5, extent=extent)


def half_resolution(images: jnp.ndarray, intrinsics: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The views at half resolution: images [V, H, W, 3] -> [V, H // 2, W // 2, 3], each pixel the mean of a
    2x2 block (an odd last row or column dropped), and their intrinsics [V, 4] (fx, fy, cx, cy) / 2 (pixel
    centres at half-integers: the small pixel j covers the big ones 2j and 2j + 1, centre 2j + 1 = 2 (j + 1/2))."""
    v, h, w, c = images.shape
    small = images[:, : h // 2 * 2, : w // 2 * 2].reshape(v, h // 2, 2, w // 2, 2, c).mean(axis=(2, 4))
    return small, intrinsics / 2.0


def host_control(cfg: SplatConfig, step: int, progress: float, params, opt_state, stats, active, rng, extent: float,
                 width: int):
    """What the host does after step `step` (1-based count of steps done) at progress in [0, 1]: the strategy's
    density-control round when its window says so, and its opacity reset every reset_every steps inside the
    window (when reset_every > 0). Returns (params, opt_state, stats, active, what: list of "control" / "reset")."""
    what, s = [], cfg.strategy
    reset_now = s.reset_every > 0 and step % s.reset_every == 0 and s.window.open(progress)
    resets = step // s.reset_every - reset_now if s.reset_every > 0 else 0  # resets done before this step
    if s.window.due(step, progress):
        gaussians = {k: np.asarray(params[k]) for k in PARAM_NAMES}  # the per-photo corrections are not Gaussians
        p, active, stats, touched = s.control(gaussians, active, stats, rng, extent, width, resets)
        if len(touched):
            opt_state = opt_state | reset_rows({k: opt_state[k] for k in PARAM_NAMES}, touched, cfg.capacity)
        params = dict(params) | {k: jnp.asarray(v) for k, v in p.items()}
        what.append("control")
    if reset_now:
        host = {k: np.asarray(v) for k, v in params.items()}
        params = dict(params, opacity=jnp.asarray(classic.reset_opacity(host, s.reset_opacity)["opacity"]))
        opt_state = dict(opt_state, opacity=reset_rows(opt_state["opacity"], np.arange(cfg.capacity), cfg.capacity))
        what.append("reset")
    return params, opt_state, stats, active, what


def view_of(seed: int, n_views: int, step: int) -> int:
    """The training view of step `step` (0-based): every epoch of n_views steps visits the views in a fresh
    random order, fixed by (seed, epoch), so a resumed run continues the same sequence."""
    epoch, k = divmod(step, n_views)
    return int(np.random.default_rng([seed, epoch]).permutation(n_views)[k])


class ViewStep:
    """The one training step of the splat method, whoever drives it (SplatModel.make_train_step for nerfkit
    train; fit.train_splats for tests and benchmarks):

        state, metrics = view_step(state, step, progress, images, poses, intrinsics)

    state: {"params", "opt_state", "aux": {"active" [capacity] bool, "grad_sum", "count", "max_radius"}};
    step: steps done before this one; progress t in [0, 1] (the budget used); hold_poses: the pose corrections
    take no step (--pose-hold-last's round). It trains view
    view_of(seed, V, step) at the SH degree and resolution the schedule gives for (step, t)
    (schedule_at: coarse to fine at half resolution), then runs the host's density control.
    metrics: loss (photometric), mse, finite, lr (the means' rate), gaussians (active after control)."""

    def __init__(self, sc: SplatConfig, opts: dict, width: int, height: int, background, extent: float):
        self.sc, self.opts, self.width, self.height, self.extent = sc, opts, width, height, extent
        self.background = jnp.asarray(background, jnp.float32)
        self.base_key = jax.random.PRNGKey(sc.seed)
        self._steps: dict = {}  # (half resolution, surface term) -> compiled step, made at its first use
        self._half: dict = {}  # the half-resolution views, made at the first coarse step

    def _step_for(self, half_now: bool, surface_now: bool):
        """The compiled step at half or full resolution, with or without the surface terms."""
        key = (half_now, surface_now)
        if key not in self._steps:
            sc = self.sc if surface_now else replace(self.sc, normal_consistency=0.0, depth_distortion=0.0)
            make = half_step if half_now else make_step
            self._steps[key] = make(sc, self.opts, self.width, self.height, with_health=True, extent=self.extent)
        return self._steps[key]

    def _at_resolution(self, plan: dict, images, intrinsics):
        """(compiled step, images, intrinsics, width) for this step's plan (schedule_at): the half-resolution
        ones in the coarse phase, the step without the surface terms before they are on."""
        fn = self._step_for(plan["half_resolution"], plan["surface"])
        if not plan["half_resolution"]:
            return fn, images, intrinsics, self.width
        half = self._half
        if half.get("of") is not images:
            small, small_intr = half_resolution(images, intrinsics)
            half.update({"of": images, "images": small, "intr": small_intr})
        return fn, half["images"], half["intr"], self.width // 2

    def __call__(self, state: dict, step: int, progress: float, images, poses, intrinsics,
                 hold_poses: bool = False) -> tuple[dict, dict]:
        sc, aux = self.sc, dict(state["aux"])
        active = np.asarray(aux["active"], bool)
        plan = schedule_at(step, progress, sc)
        lr = means_lr(progress, self.extent, sc.lrs)
        stats = {k: jnp.asarray(aux[k]) for k in ("grad_sum", "count", "max_radius")}
        params = {k: jnp.asarray(v) for k, v in state["params"].items()}
        fn, views, view_intr, w_now = self._at_resolution(plan, images, intrinsics)
        params, opt_state, stats, photo, mse, finite = fn(
            params, state["opt_state"], stats, jnp.asarray(active), views, poses, view_intr, self.background,
            view_of(sc.seed, len(poses), step), jax.random.fold_in(self.base_key, step), lr, plan["sh_degree"],
            0.0 if hold_poses else pose_lr(progress, sc.lrs), colour_lr(progress, sc.lrs))
        rng = np.random.default_rng([sc.seed, step + 1])
        params, opt_state, stats, active, _ = host_control(sc, step + 1, progress, params, opt_state, stats, active,
                                                           rng, self.extent, w_now)
        aux.update({k: stats[k] for k in stats}, active=active)
        metrics = {"loss": photo, "mse": mse, "finite": finite, "lr": jnp.float32(lr),
                   "gaussians": jnp.int32(active.sum())}
        return {"params": params, "opt_state": opt_state, "aux": aux}, metrics

    def solve_poses(self, state: dict, step: int, before: float, after: float, images, poses, intrinsics,
                    hold_poses: bool = False) -> dict:
        """state with its pose corrections solved (pose_solve.py) where the step that took the progress from before
        to after crossed one of the run's (or round's) solves; else (or with hold_poses) state as it is."""
        sc = self.sc
        if hold_poses or not (sc.pose_refine and solve_due(before, after, sc.pose_solves, 2 * sc.lrs.pose_warmup)):
            return state
        xi = solve_corrections(state["params"], state["aux"]["active"], np.asarray(poses), images,
                               np.asarray(intrinsics), self.extent, self.width, self.height, self.background,
                               schedule_at(step, before, sc)["sh_degree"], sc.backend, sc.screen_dilation,
                               share=sc.pose_solve_share)
        return {**state, "params": {**state["params"], "cam_pose": jnp.asarray(xi)}}


def schedule_at(step: int, progress: float, sc: SplatConfig) -> dict:
    """What the run does at `step` (0-based, before it) and progress t: SH degree in use, the means'
    learning rate per unit of scene extent, whether density control may run (the window), whether the
    step trains at half resolution (coarse to fine) and whether the surface terms are on."""
    return {"sh_degree": min(sc.sh_degree, sc.sh_start + step // sc.sh_interval), "lr_means": means_lr(progress, 1.0, sc.lrs),
            "control": sc.strategy.window.due(step, progress),
            "half_resolution": progress < sc.coarse_until,
            "surface": surface_terms(sc) and progress >= sc.normal_consistency_from}
