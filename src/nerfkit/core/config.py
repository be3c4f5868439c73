"""Typed configuration and presets.

A run is described by one `Config`: data, field, sampler and training settings, each a small dataclass. Presets
are complete `Config`s; the CLI starts from a preset and overrides single knobs (`--preset seed --max-steps 5000`).
The resolved config is saved as JSON in the run folder so `eval`, `render` and `--resume` rebuild the same model.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import typing
from dataclasses import dataclass
from typing import Any, Literal

from nerfkit.core import rules
from nerfkit.core.errors import ConfigError

# Settings of earlier versions that no model reads: config.json files that hold them still load.
RETIRED = frozenset({"sampler.eval_samples_per_ray"})  # the one-pass ngp renderer's budget (wavefront: its own)


@dataclass
class DataConfig:
    """Which images to load and how."""

    train_split: str | None = None
    """Frames to train on: comma-separated `split` or `split[a:b]`, e.g. "train,val[0:50]" (default: train)."""
    val_split: str | None = None
    """Frames for periodic validation, same syntax (default: val if the data has it, else test)."""
    downscale: int | None = None
    """Shrink images by this integer factor (area resampling). Overrides --target-width. Default: 1, or for
    photos the smallest power of two that brings the long side to 1600 px or less."""
    target_width: int | None = None
    """Pick the downscale factor that gives this image width (must divide the width)."""
    background: Literal["white", "black"] = "white"
    """Colour RGBA images and masked photos are composited on, and the colour rendered behind the field."""
    format: str = "auto"
    """Capture format: auto (the data folder's files), blender, nerfstudio, llff or colmap (formats/registry.py)."""
    masks: bool = True
    """Use object masks where the capture has them (pixels outside become the background); --no-masks ignores them."""
    holdout_every: int = 8
    """Formats without splits: every N-th image (sorted by name, index % N == 0) is held out as 'test'."""
    undistort: bool = False
    """Set from the data: photos of lens-distorted cameras are resampled as pinhole cameras see them, for a
    method that renders pinhole cameras only (Gaussian splats); the fields model the lens instead."""


@dataclass
class FieldConfig:
    """The radiance field F(x, d) -> (rgb, sigma)."""

    kind: str = "mlp"
    """The method (models/registry.py). mlp: positional-encoded MLP of the original NeRF. ngp: hash grid + tiny MLPs. mip: mip-NeRF (cones,
    integrated positional encoding of conical frustums, one MLP queried coarse then fine). splat: 3D Gaussian
    splatting (--preset splat; its settings are the splat section)."""
    depth: int = 8
    """MLP trunk layers D; the encoded input is concatenated back in after layer D/2."""
    width: int = 256
    """MLP trunk width W."""
    pe: bool = True
    """Positional encoding of position and direction; --no-pe feeds raw coordinates."""
    l_xyz: int = 10
    """Number of positional-encoding frequencies for positions."""
    l_dir: int = 4
    """Number of positional-encoding frequencies for view directions."""
    viewdirs: bool = True
    """Condition colour on the view direction."""
    hash_levels: int = 16
    """ngp: hash-grid levels L."""
    hash_features: int = 2
    """ngp: features per level F."""
    hash_log2_size: int = 19
    """ngp: log2 of the hash table size T per level."""
    hash_base_res: int = 16
    """ngp: resolution of the coarsest level."""
    hash_max_res: int = 1024
    """ngp: resolution of the finest level (cells across the scene box)."""
    hidden: int = 64
    """ngp: width of the density and colour MLPs."""
    antialias: bool = False
    """ngp: down-weight hash-grid levels finer than each sample's pixel footprint (Zip-NeRF's feature
    downweighting), so the field renders cleanly at scales it was not trained at."""
    bound: float | None = None
    """ngp: bounded scenes lie in the box [-bound, bound]^3; unbounded ones are contracted outside the ball
    of this radius. Default: from the data (1.5 for Blender scenes, the visual hull of masked captures,
    1.1 x the farthest camera for unbounded ones)."""
    scene_type: Literal["auto", "bounded", "unbounded"] = "auto"
    """ngp: bounded (object in a box, background colour behind) or unbounded (mip-NeRF 360 contraction, the
    background is part of the scene). auto: bounded for Blender scenes and masked captures, else unbounded."""
    warp: Literal["auto", "contract", "ndc"] = "auto"
    """ngp, unbounded scenes: how space maps into the hash grid. contract: mip-NeRF 360's contraction of all
    space into a ball (any capture); ndc: the normalised device coordinates of the mean camera, the frustum in
    front of the cameras evenly in disparity (NeRF's and TensoRF's for LLFF captures; forward-facing captures
    only, with a near plane from the capture's points). auto: ndc for forward-facing captures, else contract."""
    ndc_frame: list[float] | None = None
    """Set from the data (--warp ndc): the reference camera-to-world [R | c], 12 numbers row by row."""
    ndc_near: float | None = None
    """Set from the data (--warp ndc): the near plane's depth n in front of the reference camera."""
    ndc_extent: list[float] | None = None
    """Set from the data (--warp ndc): the slopes (a_x, a_y) the grid spans, |x / z| <= a_x, |y / z| <= a_y."""
    appearance_dim: int | None = None
    """Per-image appearance embedding size (NeRF-W); absorbs exposure / white balance. Default: 16 for photo
    captures, 0 (off) for Blender scenes and masked object captures. Held-out views use the mean embedding."""
    appearance_count: int = 0
    """Set from the data: the training images that own an appearance embedding (splats: per-photo corrections)."""

    def resolved_bound(self) -> float:
        return 1.5 if self.bound is None else self.bound

    def unbounded(self) -> bool:
        return self.scene_type == "unbounded"

    def ndc(self) -> bool:
        """Whether the field's space is a reference camera's NDC (--warp ndc, resolved from the data)."""
        return self.unbounded() and self.ndc_frame is not None

    def n_appearance(self) -> int:
        """Embedding size actually used (0 unless both the size and the image count are set)."""
        return (self.appearance_dim or 0) if self.appearance_count > 0 else 0


@dataclass
class SamplerConfig:
    """How points are placed along rays."""

    n_samples: int = 64
    """Stratified samples per ray (coarse samples when hierarchical sampling is on)."""
    n_importance: int = 0
    """Extra fine samples from the coarse weights (inverse CDF); 0 disables the fine network."""
    near: float | None = 2.0
    """Near bound of the ray interval, in z-depth (units of the camera's viewing axis); ngp default: from the data."""
    far: float | None = 6.0
    """Far bound of the ray interval; ngp default: from the data (beyond the box; 1e4 for unbounded scenes)."""
    perturb: bool = True
    """Jitter samples within their bins while training (stratified); eval uses bin midpoints."""
    occ_res: int = 64
    """ngp: occupancy grid cells per axis."""
    occ_update_every: int = 16
    """ngp: update the occupancy grid every N steps."""
    occ_warmup: int = 256
    """ngp: steps during which every update re-evaluates all cells."""
    occ_warmup_decay: float = 0.6
    """ngp: decay of a cell's running max density per update during the warm-up (0.95 afterwards, as in
    instant-ngp); faster than instant-ngp's so that a CPU run carves empty space in its first minute."""
    march_steps: int = 512
    """ngp: ray-marching steps across the box diagonal (step = 2 sqrt(3) bound / N); unbounded scenes: steps
    evenly spaced in s = g(t) over [near, far] (g: linear inside the inner ball, disparity beyond)."""
    max_samples: int = 65536
    """ngp with occupancy sampling: samples per training step; rays per step adapt to fill it (at most --batch-rays)."""
    sampling: Literal["auto", "occupancy", "proposal"] = "auto"
    """ngp: where samples go along a ray. occupancy: march the occupancy grid (instant-ngp; every occupied cell a ray
    crosses, also behind the first surface); proposal: two small proposal density fields place --field-samples samples
    where the ray's weight is (nerfacto). auto: occupancy for bounded scenes, proposal for unbounded ones."""
    proposal_samples: int = 64
    """ngp with proposal sampling: the first proposal round's samples per ray (the second takes half)."""
    field_samples: int = 32
    """ngp with proposal sampling: samples per ray of the radiance field (the last round's)."""

    def proposal_counts(self) -> tuple[int, int, int]:
        """Samples per ray of the two proposal rounds and of the field: (P, P / 2, field_samples)."""
        return self.proposal_samples, max(self.proposal_samples // 2, 2), self.field_samples

    def proposal_batch(self, batch_rays: int) -> int:
        """Rays per step with proposal sampling: every ray takes field_samples, so --max-samples / --field-samples
        of them, at most batch_rays."""
        return max(1, min(batch_rays, self.max_samples // self.field_samples))

    def resolved_sampling(self, field: FieldConfig) -> str:
        """"occupancy" or "proposal": --sampling, where auto means proposal for unbounded scenes."""
        if self.sampling != "auto":
            return self.sampling
        return "proposal" if field.unbounded() else "occupancy"


@dataclass
class TrainConfig:
    """Optimisation, logging and checkpointing."""

    max_steps: int = 200_000
    """Train until this step (in total, also with --resume)."""
    max_minutes: float | None = None
    """Stop after this many minutes of wall time (compile included), whichever comes first. Presets have a
    default (ngp 10, demo 3, seed 20, nerf and mipnerf 30); --max-steps alone lifts it."""
    batch_rays: int = 1024
    """Rays per step, drawn at random across all training images."""
    lr: float = 5e-4
    """Adam learning rate at step 0."""
    lr_decay_steps: int = 250_000
    """lr(step) = lr * decay_rate ** (step / lr_decay_steps)."""
    lr_decay_rate: float = 0.1
    """See --lr-decay-steps."""
    adam_b2: float = 0.999
    """Adam beta_2."""
    adam_eps: float = 1e-8
    """Adam epsilon."""
    seed: int = 0
    """Seeds initialisation and every step's randomness (runs are reproducible)."""
    precrop_steps: int = 0
    """For the first N steps draw rays only from the image centre (helps white-background scenes start)."""
    precrop_frac: float = 0.5
    """Fraction of the image side used during the centre-crop warm-up."""
    val_every: int = 2500
    """Validate every N steps (and at the end)."""
    val_views: int = 4
    """Number of validation views rendered at each validation (evenly spread over the val split)."""
    val_max_fraction: float = 0.1
    """Periodic validation takes at most this share of the wall time: a validation that took v seconds
    is followed by at least v (1 - f) / f seconds of training before the next (the final one always runs)."""
    ckpt_every: int = 5000
    """Write a checkpoint every N steps (and at the end or on interrupt)."""
    keep_ckpts: int = 3
    """Checkpoints kept; older ones are deleted once a newer one is safely on disk."""
    log_every: int = 50
    """Append a metrics.jsonl row every N steps."""
    chunk: int = 4096
    """Rays rendered at once in full-image rendering; bounds memory."""
    max_bad_steps: int = 5
    """Stop the run after this many consecutive non-finite losses or gradients."""
    pose_refine: Literal["on", "off"] = "off"
    """Pose refinement (every preset): a correction of each training photo's camera pose (a rotation and a translation,
    in the camera's frame) learned with the scene (the fields from the first step, splats after a warm-up). Other
    views (held-out photos in eval) are seen from their given poses moved by the similarity that best maps the given
    training poses onto the refined ones. Off by default (docs: Splats; splats: --pose-solves, --pose-rounds)."""
    devices: int | None = None
    """Local devices to split each step's rays over (data parallel; --batch-rays is the global batch, a
    multiple of the device count). Default: all local devices."""


@dataclass
class SplatSettings:
    """3D Gaussian splatting (--preset splat): Gaussians, colour, density control (read by that preset only)."""

    capacity: int = 50_000
    """Gaussians at most (fixed slots, so one compiled step serves the whole run); 3DGS-MCMC grows to it."""
    strategy: Literal["mcmc", "classic"] = "classic"
    """Density control: classic (3DGS: clone, split, prune, within --capacity slots; no opacity reset) or mcmc
    (3DGS-MCMC: all --capacity Gaussians from the start, dead ones relocated onto live ones, position noise).
    Lego, 10 min on 2 cores: classic 34.3 dB (hull init), mcmc 32.4 dB (random init, an earlier stop)."""
    sh_degree: int = 3
    """Highest spherical-harmonic degree of the view-dependent colour (0: no view dependence)."""
    sh_interval: int = 500
    """Steps per SH degree: the degree rises by one every N steps up to --sh-degree (3DGS: 1000 of 30k)."""
    ssim_lambda: float = 0.0
    """Loss = (1 - lambda) D + lambda (1 - SSIM), D the --pixel-loss; 3DGS: 0.2 (with L1). 0 by held-out PSNR (10 min,
    2 cores, with L1): maryrose 23.86 dB at 0, 23.46 at 0.05, 23.15 at 0.2 (ngp 23.39-23.57); lego 34.01 dB at 0, 34.61
    at 0.2 (ngp 33.09). D-SSIM trades PSNR for SSIM (maryrose 0.850 at 0, 0.882 at 0.2)."""
    pixel_loss: Literal["l1", "rmse"] = "rmse"
    """The loss's pixel term: rmse (the root of the mean squared error: where views disagree on a colour it fits their
    mean, which PSNR scores, L1 their median; its gradients have L1's size, so the density-control threshold holds)
    or l1 (3DGS). 10 min, 2 cores: maryrose 24.39 dB with rmse, 23.86 l1; lego 34.41/34.01 (ngp 23.4-23.6, 33.1)."""
    coarse: float | None = None
    """Coarse to fine: the first COARSE of the budget trains on the photos at half resolution (2x2 pixels averaged: a
    quarter of the rasteriser's work per step, so more steps), the rest at full resolution; 0: full resolution
    throughout; auto (default): 0.5 for photos of at least 100,000 pixels, else 0 (smaller photos gain few steps from
    it: lego at 200 px, 1.2x the steps per second and 0.8 dB lower; maryrose at 432 px, 2.6x and 0.6 dB higher)."""
    init_points: Literal["auto", "sfm", "hull", "random"] = "auto"
    """Initial Gaussians: sfm (the capture's points: sparse_pc.ply or COLMAP points3D; a capture with poses but no
    points, such as LLFF's poses_bounds.npy, gets them triangulated from its training photos at their poses, about
    1.5 s a photo, cached in ~/.cache/nerfkit/points), hull (uniform in the visual hull of the masks or alpha
    channel), random (uniform in the scene box) or auto (the capture's points; else hull where it has masks or alpha;
    else triangulated; random only where no point could be triangulated)."""
    init: str | None = None
    """A splat file to start from instead of --init-points: .ply (Inria layout, from nerfkit, gsplat, 3DGS, Brush,
    SuperSplat), .spz, .splat, .glb or .gltf, in the capture's own coordinates (as nerfkit export splat writes
    them); training fine-tunes it on this capture. --capacity must hold its Gaussians."""
    init_sh_degree: int | None = None
    """The SH degree of the --init file, filled in when the run starts (never from the command line): --resume
    takes the Gaussians from the run's checkpoint and this degree from its config, so the file may be gone."""
    far_points: Literal["auto", "on", "off"] = "auto"
    """A background to start from: a tenth of --capacity Gaussians on a sphere 3x as far from the scene's centre as
    the farthest camera, or behind 95% of the SfM points where they reach further (a forward-facing capture's far
    wall), each coloured by a training photo that sees it (on a forward-facing capture, where the rays of pixels
    drawn over the photos meet that sphere), so that what lies far away (walls, sky) has Gaussians of its own instead
    of being smeared over the near ones. auto: on for photos without masks (unbounded scenes), off for masked objects
    and Blender scenes."""
    random_background: Literal["auto", "on", "off"] = "off"
    """Train on a random background colour per step where the photos have masks or an alpha channel (the photo is
    composited onto it by its alpha): a surface can then not be left see-through where its colour matches the
    background (a light floor on white), which the rendered opacity, and so `export mesh`, would show as holes. auto:
    on for captures with masks or alpha."""
    normal_consistency: float = 0.0
    """Weight of a training term that lays each Gaussian flat along the surface its neighbours' depth describes
    (2DGS's normal consistency: the blended normals of the Gaussians against the normals of the rendered
    depth), for runs meant for `export mesh`; 0: off. Costs steps per second and some PSNR (docs: Export)."""
    normal_consistency_from: float = 0.0
    """The share of the budget trained before the --normal-consistency and --depth-distortion terms come on (2DGS
    starts them after a warm-up, so that the Gaussians find the colours first): 0 (default) from the first step.
    lego, 10 minutes, weight 0.15 from 0.3: 31.0 dB held out (28.2 with 0.15 from the start) and a mesh that keeps
    both the silhouettes and the depth (docs: Export)."""
    depth_distortion: float = 0.0
    """Weight of a training term that draws the Gaussians a ray passes together in depth (2DGS's depth distortion:
    the blended squared differences of their depths along each ray, relative to the depth), for runs meant for
    `export mesh`; 0: off. On from --normal-consistency-from, as that term is (docs: Export)."""
    screen_dilation: float = 0.3
    """px^2 added to each Gaussian's footprint on the screen (3DGS's 0.3). 0.1 keeps thin parts and surfaces (docs:
    Export), but other viewers draw with 0.3 (`export splat` says how smeared): keep 0.3 to share."""
    pose_rounds: int = 1
    """With --pose-refine on: the budget in N equal rounds, each after the first starting the Gaussians over from the
    initial points while every photo's pose and colour corrections are kept (docs: Splats). 1: one round."""
    pose_hold_last: Literal["on", "off"] = "off"
    """With --pose-rounds 2 or more: on: the final round holds the poses the rounds before refined (docs: Corrections)."""
    pose_solves: int = 0
    """With --pose-refine on: N times over the budget (each round) every photo's pose takes a Levenberg-Marquardt step
    against the Gaussians as they stand, the last after the last step. For scenes seen all around (docs: Splats)."""
    pose_solve_share: float = 1.0
    """With --pose-solves: the share of each solve's step the poses take (1: all of it; docs: Corrections)."""
    pose_warmup: float = 0.1
    """With --pose-refine on: the share of the budget (of each round) before the poses move; their rate then ramps up
    over as long again, and the --pose-solves start after the ramp (docs: Corrections)."""
    pose_lr: float = 1e-4
    """With --pose-refine on: the poses' Adam rate after the warm-up's ramp, a tenth by the end (0: solves alone)."""
    appearance: Literal["auto", "on", "off"] = "auto"
    """A colour transform per training photo (exposure and white balance change from photo to photo), learned with
    the Gaussians; held-out photos use the mean of the training photos' transforms. auto: on for photo captures
    without masks, off for Blender scenes and masked object captures (as the fields' --appearance-dim)."""
    colour_lr: float | None = None
    """The Gaussians' colour learning rate (Adam, SH units; the higher bands a twentieth of it). Unset: 3DGS's 2.5e-3
    for photos without masks, 2e-2 for masked objects and Blender scenes, which need their colours fast on a CPU
    budget (buddha held out: 19.88 dB at 2.5e-3 against 19.25 at 2e-2; maryrose 24.48 against 23.66; docs: Splats)."""
    colour_transform: Literal["gain", "affine"] = "gain"
    """--appearance's transform: gain (a gain per channel: 3 numbers a photo, what exposure and white balance do) or
    affine (a 3x3 matrix and an offset: 12, which also soak up the scene's errors; docs: Splats)."""
    colour_transform_lr: float = 3e-3
    """--appearance's transforms' learning rate (Adam), log-linearly down to a tenth by the end (docs: Splats)."""
    backend: str = "auto"
    """The rasteriser: auto (pallas on a GPU, numba elsewhere), numba (CPU tile kernels through a host callback), pallas
    (Triton tile kernels on a GPU; interpreted on a CPU, far slower) or reference (pure JAX; models/splat/backends.py)."""

    def loss_name(self) -> str:
        """The photometric loss in words: "L1", "RMSE" or "0.8 L1 + 0.2 D-SSIM"."""
        lam, pixel = self.ssim_lambda, self.pixel_loss.upper()
        return f"{1 - lam:g} {pixel} + {lam:g} D-SSIM" if lam else pixel


@dataclass
class Config:
    """A complete nerfkit run."""

    data: DataConfig = dataclasses.field(default_factory=DataConfig)
    field: FieldConfig = dataclasses.field(default_factory=FieldConfig)
    sampler: SamplerConfig = dataclasses.field(default_factory=SamplerConfig)
    train: TrainConfig = dataclasses.field(default_factory=TrainConfig)
    splat: SplatSettings = dataclasses.field(default_factory=SplatSettings)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @staticmethod
    def sections() -> dict[str, type]:
        """{section name: its settings dataclass}, in declaration order: a new section is one dataclass and one
        field here (flags, --help, the config file and the type check read this)."""
        return dict(_sections())

    @staticmethod
    def from_dict(d: dict[str, Any]) -> "Config":
        """Rebuild a config (e.g. a run folder's config.json); ConfigError if it is not a valid one. Settings
        that earlier versions wrote and no model reads any more (RETIRED) are dropped; a splat section written
        before --pixel-loss existed gets "l1", the loss those runs trained with (so --resume keeps it)."""
        try:
            sections = {k: {n: v for n, v in d.get(k, {}).items() if f"{k}.{n}" not in RETIRED}
                        for k in Config.sections()}
            missing = [k for k in ("data", "field", "sampler", "train") if k not in d]  # every version wrote these
            if missing:
                raise KeyError(missing[0])
            # configs written before --sampling existed: their samples came from the occupancy grid
            sections["sampler"].setdefault("sampling", "occupancy")
            sections["field"] = {**FIELD_BEFORE, **sections["field"]}
            sections["splat"] = {**SPLAT_BEFORE, **sections["splat"]} if sections["splat"] else {}  # may have none
            sections["train"].setdefault("pose_refine", "off")
            cfg = Config(**{k: cls(**sections[k]) for k, cls in Config.sections().items()})
        except (KeyError, TypeError, AttributeError) as e:
            raise ConfigError(f"config is not a nerfkit config ({e})") from None
        return validate(cfg)


# What a field or splat config written before a setting existed trained with, where that differs from today's
# default: before --warp an unbounded field was contracted (--resume, eval and checkpoints must not move it into NDC).
FIELD_BEFORE = {"warp": "contract"}
SPLAT_BEFORE = {"pixel_loss": "l1", "appearance": "off", "far_points": "off", "random_background": "off",
                "normal_consistency": 0.0, "normal_consistency_from": 0.0, "depth_distortion": 0.0,
                "colour_transform": "affine", "colour_lr": 2e-2, "colour_transform_lr": 1e-3}


@functools.cache
def _sections() -> tuple[tuple[str, type], ...]:
    hints = typing.get_type_hints(Config)  # (resolving annotations compiles them: once)
    return tuple((f.name, hints[f.name]) for f in dataclasses.fields(Config))


def validate(cfg: Config) -> Config:
    """Raise ConfigError naming the first bad value; return cfg unchanged otherwise (the rules: rules.py)."""
    if not isinstance(cfg, Config):
        raise ConfigError(f"expected a nerfkit Config, got {type(cfg).__name__}")
    rules.check(cfg)
    return cfg
