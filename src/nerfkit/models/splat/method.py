"""Gaussian splatting as a nerfkit method: the model object the trainer (training/trainer.py), the image
renderer (render/images.make_renderer) and the exports hold.

nerfkit's run loop (training/trainer.Trainer) asks a model for five things; the radiance fields
(models/nerf.py, mipnerf.py, ngp.py) answer with rays, this class with whole views:

    bind_data(capture, data, log)   the training data it initialises from (SfM points, scene extent)
    init(key) -> (params, aux)      parameters and non-trainable state (checkpointed together)
    make_optimizer(cfg)             (optimiser with .init(params), schedule(step) for the log)
    make_train_step(optimizer, data, cfg)  step(state, step, images, poses) -> (state, metrics)
    renderer(chunk)                 .render_camera(params, aux, c2w, camera) -> rgb, depth, opacity
                                    (.render_cameras: a list of views in one call)

One step is train.ViewStep (fit.train_splats drives it too): one training view (a random order per epoch, fixed by
the seed), an Adam step (train.make_step) and, on the host, its strategy's density control (strategy.py). params are
all `capacity` slots; aux["active"] marks the slots in use, aux holds the classic statistics and aux["clock"] the
seconds spent in steps, so that progress t = max(step / max_steps, clock / budget), which schedules the means'
learning rate and the density-control window, survives --resume.
"""

from __future__ import annotations

import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from nerfkit.core.errors import ConfigError, DataError
from nerfkit.data.normalize import forward_facing, sample_visual_hull
from nerfkit.data.points import far_points_through_photos, far_radius, far_sphere_points, transform_points
from nerfkit.models.base import Supports
from nerfkit.models.splat import densify as classic
from nerfkit.models.splat.backends import backend
from nerfkit.models.splat.gaussians import PARAM_NAMES, init_from_points, init_random, intrinsics_of
from nerfkit.models.splat.optim import LearningRates, colour_lr_for, colour_rates, init_state, make_optimizers, means_lr
from nerfkit.models.splat.pose_solve import check_settings, describe_pose, unused_settings
from nerfkit.models.splat.project import LOWPASS_DILATION
from nerfkit.models.splat.renderer import SplatRenderer
from nerfkit.models.splat.rounds import in_round, round_aux, within_round
from nerfkit.models.splat.train import SplatConfig, ViewStep, initial_params
from nerfkit.models.splat.transform import transform_gaussians
from nerfkit.rays.correction import camera_extent

RANDOM_INIT = 100_000  # random Gaussians in the box without SfM points (3DGS's Blender init), fewer if capacity is
# Their scales: this x the mean distance to the 3 nearest (1.0 in 3DGS). Measured on lego (seed protocol, 2 shared
# cores, benchmarks/splat_lego.py --minutes 2.5): 0.3 gives 26.25 dB at 2 min and 5.8 steps/s, against 24.47 dB and
# 5.1 steps/s at 1.0 (50k random Gaussians ~13 px wide cost the tile rasteriser 3x more per step at first).
RANDOM_INIT_SCALE = 0.3
# Inside the visual hull of the silhouettes (masked captures, Blender's alpha) rather than the whole box: lego (seed
# protocol, 2000 steps, all 50 views of val[50:100], 2 shared cores) 31.54 dB at 0.3 x the neighbour distance, 31.33 at
# 1.0, against 30.67 from the box (random).
HULL_INIT_SCALE = 0.3
# The hull init fills half the slots; classic density control clones and splits into the rest where the photos ask
# (filled, it could only prune: the Gaussians sealed inside the object keep their slots). maryrose (masks, --downscale 2,
# 10 min through the CLI, --coarse 0.5, held-out photos): 23.20 dB from half the slots, 22.94 dB from all of them.
HULL_INIT_SHARE = 0.5
# --coarse unset: half resolution for the first COARSE_AUTO of the budget on photos of at least COARSE_MIN_PIXELS,
# where the rasteriser dominates the step. 10 min through the CLI, 2 cores: maryrose (432 x 432, 187k px) runs 2.6x
# the steps per second at half resolution and gains 0.6 dB (22.33 -> 22.94); lego (200 x 200, 40k px) 1.2x, where
# projection and Adam over every Gaussian cost as much as the pixels, and loses 0.8 dB (34.61 -> 33.84 dB).
COARSE_AUTO = 0.5
COARSE_MIN_PIXELS = 100_000
# --far-points: FAR_SHARE of --capacity on a sphere FAR_RADIUS x the farthest camera's distance from the centre, or
# beyond the FAR_QUANTILE of the SfM points' distances where they reach further (data/points.far_radius).
FAR_SHARE = 0.1
FAR_RADIUS = 3.0
FAR_QUANTILE = 0.95


def coarse_share(coarse: float | None, pixels: int | None) -> float:
    """The share of the budget trained at half resolution: --coarse when set; unset, COARSE_AUTO for photos
    of at least COARSE_MIN_PIXELS pixels (pixels None: not known yet, 0)."""
    if coarse is not None:
        return coarse
    return COARSE_AUTO if pixels is not None and pixels >= COARSE_MIN_PIXELS else 0.0


def splat_config(cfg, pixels: int | None = None) -> SplatConfig:
    """train.SplatConfig of a nerfkit Config (--preset splat): capacity, strategy, SH, loss, seed, and the
    coarse phase for training photos of `pixels` pixels each (coarse_share)."""
    g = cfg.splat
    return SplatConfig(capacity=g.capacity, strategy=g.strategy, sh_degree=g.sh_degree, sh_interval=g.sh_interval,
                       ssim_lambda=g.ssim_lambda, pixel_loss=g.pixel_loss, coarse_until=coarse_share(g.coarse, pixels),
                       seed=cfg.train.seed, init_box=cfg.field.resolved_bound(), backend=g.backend,
                       appearance=g.appearance == "on", colour_transform=g.colour_transform,
                       pose_refine=cfg.train.pose_refine == "on",
                       n_views=cfg.field.appearance_count, random_background=g.random_background == "on",
                       normal_consistency=g.normal_consistency, normal_consistency_from=g.normal_consistency_from,
                       depth_distortion=g.depth_distortion, screen_dilation=g.screen_dilation,
                       pose_solves=g.pose_solves, pose_solve_share=g.pose_solve_share,
                       lrs=colour_rates(LearningRates(pose_warmup=g.pose_warmup, cam_pose=g.pose_lr), g.colour_lr,
                                        g.colour_transform_lr))


def progress_of(step: int, clock: float, cfg) -> float:
    """t = max(step / max_steps, clock / (60 max_minutes)) in [0, 1]: the fraction of the budget used."""
    t = cfg.train
    by_time = clock / (60.0 * t.max_minutes) if t.max_minutes else 0.0
    return float(min(1.0, max(step / max(t.max_steps, 1), by_time)))


def _describe_coarse(coarse: float | None) -> str:
    if coarse is None:
        return f"half resolution for the first {COARSE_AUTO:.0%} on photos of >= {COARSE_MIN_PIXELS:,} pixels, "
    return f"half resolution for the first {coarse:.0%} of the budget, " if coarse else ""


def _describe_surface(g) -> str:
    terms = [f"{name} {w:g}" for name, w in (("normal consistency", g.normal_consistency),
                                             ("depth distortion", g.depth_distortion)) if w]
    if not terms:
        return ""
    late = f" from {g.normal_consistency_from:.0%} of the budget" if g.normal_consistency_from else ""
    return f"; {', '.join(terms)}{late}"


class SplatOptimizer:
    """Adam per parameter group with 3DGS's rates (optim.py); init(params) -> {group: optax state}."""

    def __init__(self, lrs: LearningRates, extent: float, eps: float, corrections=()):
        self.opts = make_optimizers(lrs, extent, eps, corrections)

    def init(self, params: dict) -> dict:
        return init_state(self.opts, params)


class SplatModel:
    """3D Gaussian splatting behind nerfkit's model interface (see the module docstring)."""

    supports = Supports(family="image", parallel="views", mesh=False, lens=False, appearance=False, gaussians=True,
                        points=True, pose_refine=True, fit_poses=True)
    title = "Gaussian splatting"
    reads = frozenset(f"splat.{n}" for n in (
        "capacity", "strategy", "sh_degree", "sh_interval", "ssim_lambda", "pixel_loss", "coarse", "init_points",
        "init", "init_sh_degree", "backend", "appearance", "far_points", "random_background", "normal_consistency",
        "normal_consistency_from", "depth_distortion", "screen_dilation", "colour_transform", "colour_lr",
        "colour_transform_lr", "pose_rounds", "pose_hold_last", "pose_solves", "pose_solve_share", "pose_warmup",
        "pose_lr")) | {"train.pose_refine"}

    @staticmethod
    def describe(cfg) -> str:
        """One line naming the model with the settings it reads (and only those)."""
        g = cfg.splat
        return (f"splat: up to {g.capacity} Gaussians ({g.strategy} density control), SH degree {g.sh_degree}"
                f"{f' raised every {g.sh_interval} steps' if g.sh_degree else ''}, loss {g.loss_name()}, "
                f"{_describe_coarse(g.coarse)}"
                f"{f'init from {Path(g.init).name}' if g.init else f'{g.init_points} init'}, one view per step"
                f"{f'; a colour transform per photo ({g.colour_transform})' if g.appearance == 'on' else ''}"
                f"{'; far points' if g.far_points == 'on' else ''}"
                f"{'; random background' if g.random_background == 'on' else ''}"
                f"{_describe_surface(g)}"
                f"{'' if g.screen_dilation == LOWPASS_DILATION else f'; screen dilation {g.screen_dilation:g} px^2'}"
                f"{describe_pose(cfg)}"
                f"{'' if g.backend == 'auto' else f'; {g.backend} rasteriser'}")

    @staticmethod
    def resolve_settings(cfg, photos: bool, n_train: int, log=print) -> None:
        """--appearance and --far-points auto: on for photos without masks, --random-background auto: on for the
        others, --colour-lr unset: optim.colour_lr_for (registry.resolve_settings); the corrections' count
        (field.appearance_count): the training photos' if one is."""
        g = cfg.splat
        g.colour_lr = colour_lr_for(photos) if g.colour_lr is None else g.colour_lr
        if g.appearance == "auto":
            g.appearance = "on" if photos else "off"
        if g.far_points == "auto":
            g.far_points = "on" if photos else "off"
        if g.random_background == "auto":
            g.random_background = "off" if photos else "on"
        if g.appearance == "on":
            log(f"appearance: a colour transform per training photo ({n_train}; --colour-transform "
                f"{g.colour_transform}); held-out photos use their mean (--appearance off: none)")
        cfg.field.appearance_count = n_train if "on" in (g.appearance, cfg.train.pose_refine) else 0

    @staticmethod
    def check(cfg) -> None:
        """ConfigError for a --backend that is not in the table (backends.py) or pose settings out of range
        (pose_solve.check_settings: rounds, solves, their share, the warm-up)."""
        backend(cfg.splat.backend)
        check_settings(cfg.splat)

    @staticmethod
    def unused(cfg, capture=None) -> dict[str, str]:
        """Settings left unread at these values: field.kind (splats are no field), normal_consistency_from without
        a surface term, sh_interval at SH degree 0, init_points auto on a capture without SfM points, colour_transform
        without colour transforms, the pose settings without pose refinement (pose_solve.unused_settings)."""
        out = {"field.kind": "Gaussian splats are their own method, not a field; pick a NeRF preset (--preset ngp)"}
        if cfg.splat.init:
            out["splat.init_points"] = f"the Gaussians start from --init {cfg.splat.init}"
            out["splat.far_points"] = f"the Gaussians start from --init {cfg.splat.init}"
        if cfg.splat.normal_consistency == 0 and cfg.splat.depth_distortion == 0:
            out["splat.normal_consistency_from"] = ("the surface terms are off; give one a weight "
                                                    "(--normal-consistency 0.15)")
        if cfg.splat.sh_degree == 0:
            out["splat.sh_interval"] = "the colour has no view dependence to raise (--sh-degree 0)"
        out.update(unused_settings(cfg.train.pose_refine == "on", cfg.splat.pose_solves))
        if cfg.splat.appearance == "off" or (cfg.splat.appearance == "auto" and not getattr(capture, "photos", True)):
            out["splat.colour_transform"] = out["splat.colour_transform_lr"] = "no colour transforms (--appearance on)"
        if (capture is not None and cfg.splat.init_points == "auto" and capture.points is None
                and (capture.has_masks or capture.alpha)):
            out["splat.init_points"] = (f"the capture {capture.root} has no SfM points (sparse_pc.ply, COLMAP "
                                        f"points3D) and has silhouettes: the Gaussians start in their visual hull")
        return out

    def wants_points(self, capture) -> bool:
        """Whether a capture should get points triangulated at its poses before bind_data: it has none, and
        --init-points is sfm, or auto on photos without masks or alpha (those start in the visual hull)."""
        choice = self.cfg.splat.init_points
        if self.cfg.splat.init or capture.points is not None or choice not in ("auto", "sfm"):
            return False
        return choice == "sfm" or not (capture.has_masks or capture.alpha)

    def __init__(self, cfg):
        self.cfg = cfg
        self.loss_name = cfg.splat.loss_name()
        self.sc = splat_config(cfg)
        self.background = (1.0, 1.0, 1.0) if cfg.data.background == "white" else (0.0, 0.0, 0.0)
        self.extent = 1.0
        self.init_gaussians: dict | None = None
        self.init_note = "random in the box (no training data bound)"

    def bind_data(self, capture, data, log=print) -> None:
        """Take the scene extent from the training poses and the initial Gaussians (--init-points): the
        capture's SfM points (in the normalised frame); else, with masks or alpha, uniform in the visual
        hull of the training silhouettes; else random in the scene box."""
        self.extent = camera_extent(data.poses)
        if data.sizes is not None:
            raise DataError(f"{capture.root}: --preset splat trains on images of one size; this selection has "
                            f"several (multiscale data): pick one level with --train-split")
        self.sc = splat_config(self.cfg, data.width * data.height)
        if self.sc.corrections and self.sc.n_views != len(data.poses):
            raise DataError(f"{capture.root}: the run's per-photo corrections are for {self.sc.n_views} training "
                            f"photos, this selection has {len(data.poses)}")
        for cam in data.cameras[:1]:
            try:
                intrinsics_of(cam)
            except ValueError as e:
                raise DataError(f"{capture.root}: {e}") from None
        if self.cfg.splat.init:
            self._init_from_file(data)
            log(f"splat init: {self.init_note}; scene extent {self.extent:.3g}; {self._coarse_note(data)}")
            return
        choice = self.cfg.splat.init_points
        has_points = capture.points is not None and choice in ("auto", "sfm")
        if choice == "sfm" and not has_points:
            raise DataError(f"{capture.root}: --init-points sfm, but the capture has no SfM points (sparse_pc.ply "
                            f"or a COLMAP model) and none could be triangulated at its poses; use --init-points "
                            f"random")
        if choice == "hull" and data.alphas is None:
            raise DataError(f"{capture.root}: --init-points hull, but the capture has neither masks nor an alpha "
                            f"channel; use --init-points random")
        sfm = None
        if has_points and len(capture.points) >= 4:  # the capture's SfM points (data/capture.py), normalised
            pts = transform_points(capture.points, data.transform)
            self.init_gaussians = init_from_points(pts, capture.point_colors)
            sfm = pts
            self.init_note = f"{len(pts)} SfM points of {Path(capture.points_file).name}"
        if self.init_gaussians is None and choice in ("auto", "hull") and data.alphas is not None:
            self._init_in_hull(data)
            if self.init_gaussians is None and choice == "hull":
                raise DataError(f"{capture.root}: --init-points hull, but the training silhouettes' visual hull "
                                f"is empty (do the masks and poses agree?); use --init-points random")
        if self.init_gaussians is None:
            self.init_note = f"{min(RANDOM_INIT, self.sc.capacity)} random points in the box " \
                             f"[-{self.sc.init_box:g}, {self.sc.init_box:g}]^3"
        far = self.cfg.splat.far_points
        if far == "on" or (far == "auto" and not (capture.has_masks or capture.alpha)):
            self._add_far_points(data, sfm)
        log(f"splat init: {self.init_note}; scene extent {self.extent:.3g}; {self._coarse_note(data)}")

    def _init_from_file(self, data) -> None:
        """The Gaussians of --init FILE (capture coordinates), moved into the normalised frame (data.transform), and
        the file's SH degree into cfg.splat.init_sh_degree (the run's config.json). A run whose config already
        holds that degree is being resumed: where the file is gone, its Gaussians come from the run's checkpoint
        and the degree from the config."""
        from dataclasses import replace

        from nerfkit.models.splat.formats import read_gaussians

        path, known = Path(self.cfg.splat.init), self.cfg.splat.init_sh_degree
        if known is not None and not path.is_file():
            self.sc = replace(self.sc, sh_start=known)
            self.init_note = f"resumed from a run that started from {path.name} (SH degree {known})"
            return
        g, degree, fmt = read_gaussians(path, "--init")
        if len(g["means"]) > self.sc.capacity:
            raise ConfigError(f"--init {path}: {len(g['means']):,} Gaussians, more than --capacity "
                              f"{self.sc.capacity:,}; pass --capacity {len(g['means'])} or more")
        self.init_gaussians = transform_gaussians(g, np.asarray(data.transform, np.float64))
        self.sc = replace(self.sc, sh_start=degree)  # the file's bands are in use from the first step
        self.cfg.splat.init_sh_degree = degree
        self.init_note = f"{len(g['means']):,} Gaussians of {path.name} ({fmt.name}, SH degree {degree})"

    def _coarse_note(self, data) -> str:
        """What the coarse phase will be, and why when --coarse was left to the photos' size."""
        share, px = self.sc.coarse_until, data.width * data.height
        what = f"half resolution for the first {share:.0%} of the budget" if share else "full resolution throughout"
        if self.cfg.splat.coarse is not None:
            return what
        return f"{what} (photos of {px:,} pixels {'>=' if share else '<'} {COARSE_MIN_PIXELS:,}; set --coarse)"

    def _add_far_points(self, data, sfm: np.ndarray | None) -> None:
        """Add FAR_SHARE x capacity Gaussians on the far sphere (data/points.far_radius: beyond the cameras, and
        beyond the SfM points sfm [N, 3] where they reach further), coloured by the training photos, to the initial
        ones (random ones in the box first, where there are none yet): uniform over the sphere, the ones a photo
        sees (data/points.far_sphere_points); for a forward-facing capture (data/normalize.forward_facing),
        where the rays of pixels drawn over the photos leave it (far_points_through_photos)."""
        radius = far_radius(data.poses, sfm, FAR_RADIUS, FAR_QUANTILE)
        ahead = forward_facing(np.asarray(data.poses))
        draw = far_points_through_photos if ahead else far_sphere_points
        pts, colours = draw(int(FAR_SHARE * self.sc.capacity), radius, data.poses, data.cameras, data.images,
                            self.sc.seed)
        if len(pts) < 4:
            return
        far = init_from_points(pts, colours, self.sc.init_opacity)
        near = self.init_gaussians
        if near is None:
            n = min(RANDOM_INIT, self.sc.capacity - len(pts))
            near = init_random(n, self.sc.init_box, self.sc.seed, self.sc.init_opacity)
            near["log_scales"] = near["log_scales"] + np.float32(np.log(RANDOM_INIT_SCALE))
            self.init_note = f"{n} random points in the box [-{self.sc.init_box:g}, {self.sc.init_box:g}]^3"
        self.init_gaussians = {k: np.concatenate([np.asarray(near[k], np.float32), far[k]]) for k in PARAM_NAMES}
        self.init_note += (f", and {len(pts)} on a far sphere of radius {radius:.3g} coloured by the photos"
                           + (" (where their pixels' rays meet it: a forward-facing capture)" if ahead else ""))

    def _init_in_hull(self, data) -> None:
        """Grey Gaussians (as the random init's) uniform in the visual hull of the training silhouettes, their
        scales HULL_INIT_SCALE x the distance to their neighbours."""
        n = min(RANDOM_INIT, int(HULL_INIT_SHARE * self.sc.capacity))
        pts = sample_visual_hull(n, self.sc.init_box, data.poses, data.cameras, data.alphas, self.sc.seed)
        if pts is None:
            return
        g = init_from_points(pts, np.full((len(pts), 3), 0.5, np.float32), self.sc.init_opacity)
        g["log_scales"] = g["log_scales"] + np.float32(np.log(HULL_INIT_SCALE))
        self.init_gaussians = g
        self.init_note = f"{len(pts)} points uniform in the visual hull of the training silhouettes"

    def init(self, key=None):
        """(params: all capacity slots, aux: active mask, classic statistics, clock) as numpy arrays."""
        sc = self.sc
        if self.init_gaussians is None:
            from dataclasses import replace

            sc = replace(sc, init_count=min(RANDOM_INIT, sc.capacity), init_scale=RANDOM_INIT_SCALE)
        params, active = initial_params(sc, self.init_gaussians)
        stats = {k: np.zeros(sc.capacity, np.float32) for k in classic.zero_stats(1)}  # numpy: eval_shape-safe
        return params, {"active": active, **stats, "clock": np.zeros((), np.float32), **round_aux(self._rounds())}

    def _rounds(self) -> int:
        """--pose-rounds where pose refinement is on, else 1."""
        return self.cfg.splat.pose_rounds if self.cfg.train.pose_refine == "on" else 1

    def make_optimizer(self, cfg):
        """(SplatOptimizer, schedule): schedule(step) is the means' rate per unit extent by step count alone
        (the time budget can end the decay sooner; the log's lr column is the rate used)."""
        return (SplatOptimizer(self.sc.lrs, self.extent, cfg.train.adam_eps, self.sc.corrections),
                lambda step: means_lr(step / max(cfg.train.max_steps, 1), 1.0, self.sc.lrs))

    def make_train_step(self, optimizer, data, cfg, mesh=None):
        """step(state, step, images, poses) -> (state, metrics: loss, mse, finite, lr, gaussians); runs the
        jitted view step (train.make_step) and then the host's density control."""
        view_step = ViewStep(self.sc, optimizer.opts, data.width, data.height, self.background, self.extent)
        intrinsics = jnp.asarray([intrinsics_of(c) for c in data.cameras], jnp.float32)
        kept: dict = {}
        hold_last = self._rounds() > 1 and self.cfg.splat.pose_hold_last == "on"

        def step_fn(state, step, images, poses):
            t0 = time.perf_counter()
            clock = float(state["aux"]["clock"])
            if kept.get("of") is not images:  # made once per images array
                kept.update({"of": images, "views": self.training_views(images, data.alphas)})
            images = kept["views"]
            at, n = int(step), self._rounds()
            step, progress = at, progress_of(at, clock, cfg)
            if n > 1:
                state, step, progress = in_round(state, step, progress, n, self.init, self.sc.corrections, optimizer)
            hold = hold_last and int(state["aux"].get("round", 0)) == n - 1  # --pose-hold-last's round
            state, metrics = view_step(state, step, progress, images, poses, intrinsics, hold)
            after = within_round(progress_of(at + 1, clock + time.perf_counter() - t0, cfg), n, state["aux"])
            state = view_step.solve_poses(state, step, progress, after, images, poses, intrinsics, hold)
            state["aux"]["clock"] = np.float32(clock + time.perf_counter() - t0)
            return state, metrics

        return step_fn

    def training_views(self, images, alphas):
        """The views the step trains on: images [V, H, W, 3], or with --random-background on and masks or alpha
        (alphas [V, H, W] uint8) RGBA views [V, H, W, 4], which train on a random background (train._loss_fn)."""
        if not (self.sc.random_background and alphas is not None):
            return images
        return jnp.concatenate([jnp.asarray(images, jnp.float32), jnp.asarray(alphas, jnp.float32)[..., None] / 255.0],
                               -1)

    def renderer(self, chunk: int = 0) -> SplatRenderer:
        return SplatRenderer(self)
