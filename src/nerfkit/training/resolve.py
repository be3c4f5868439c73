"""Settings that come from the data, not the preset: splits, scene type, scene box,
near / far and appearance embeddings. A run's config.json holds the resolved values, so
eval, render and --resume rebuild exactly the trained model.

    splits        train: "train"; validation: "val" if the data has it, else "test"
    scene type    bounded for Blender scenes, masked captures and instant-ngp files with
                  aabb_scale 1; unbounded otherwise (mip-NeRF 360 contraction)
    bound         Blender: 1.5 (the scenes' convention); masked: the masks' visual hull
                  (normalize.masked_bound); unbounded: inner ball = 1.1 x the farthest camera
    near, far     bounded: 0 and past the far side of the box from the farthest camera;
                  unbounded: 0.05 (cameras sit at radius 4) and 1e4
    sampling      ngp: the occupancy march for bounded scenes, proposal sampling for unbounded ones
    warp          ngp, unbounded scenes: NDC of the mean camera for forward-facing captures (near plane from
                  the points; data/normalize.ndc_space), else the contraction
    lens          the photos of a lens-distorted camera are undistorted for a method that renders pinhole
                  cameras only (lens_plan; Gaussian splats), the fields model the lens
    appearance    16 per image for photo captures without masks (exposure and white balance
                  change between their photos); off for Blender scenes and masked object
                  captures (fixed exposure; on a turntable the embeddings soak up the shading
                  that changes as the object turns, and the mean embedding of held-out views
                  cannot give it back: -1.1 dB on maryrose's test photos, 4-minute runs);
                  for Gaussian splats (--appearance) a colour transform per photo, on for the same captures
"""

from __future__ import annotations

import copy
import math

import numpy as np

from nerfkit.core.config import Config, validate
from nerfkit.core.errors import ConfigError
from nerfkit.data.capture import Capture, SceneData
from nerfkit.data.capture import scene_type as capture_scene_type
from nerfkit.data.normalize import FORWARD_DEGREES, forward_facing, masked_bound, ndc_space, view_spread
from nerfkit.data.points import transform_points
from nerfkit.models import registry

UNBOUNDED_NEAR, UNBOUNDED_FAR = 0.05, 1e4
APPEARANCE_DIM = 16


def default_splits(cfg: Config, cap_splits: list[str] | None = None) -> tuple[str, str]:
    """(train spec, val spec): the config's, else "train" and "val" (or "test" where there is no val)."""
    d = cfg.data
    val = d.val_split
    if val is None:
        val = "val" if cap_splits is None or "val" in cap_splits else "test"
    return d.train_split or "train", val


def lens_plan(cfg: Config, cap: Capture, spec: str) -> tuple[bool, str | None]:
    """(undistort, what to say or None): whether the photos of `spec` must be undistorted for the method (it
    renders pinhole cameras only, Supports.lens, and a camera has lens distortion), and the log line's start."""
    distorted = [f.camera for f in cap.frames(spec) if f.camera.distorted]
    if not distorted:
        return False, None
    model = distorted[0].model
    method = registry.method_class(cfg)
    if method.supports.lens:
        return False, f"lens: {model} camera with distortion; every ray goes through the lens model"
    return True, (f"lens: {model} camera with distortion; {method.title} renders pinhole cameras, "
                  f"so the photos are undistorted (COLMAP's undistorter; held-out views alike)")


def scene_type(cfg: Config, cap: Capture) -> tuple[str, str]:
    """(bounded | unbounded, why) of the capture under cfg's --scene-type (data/capture.py)."""
    return capture_scene_type(cfg.field.scene_type, cap)


def resolve_config(cfg: Config, cap: Capture, train: SceneData, log=print) -> Config:
    """A copy of cfg with every data-dependent default filled in (see module docstring)."""
    cfg = copy.deepcopy(cfg)
    f, s = cfg.field, cfg.sampler
    supports = registry.method_class(cfg).supports
    scene, why = scene_type(cfg, cap)
    notes = []
    if supports.unbounded or f.scene_type != "auto":
        f.scene_type = scene
    warp_notes = _resolve_warp(cfg, cap, train)
    dist = np.linalg.norm(train.poses[:, :3, 3], axis=-1)
    if f.bound is None:
        if scene == "unbounded":
            f.bound = _round_up(1.1 * float(dist.max()))
            where = "inner ball: 1.1 x the farthest camera"
        elif cap.format != "blender" and train.alphas is not None and train.has_masks:
            b = masked_bound(train.poses, train.cameras, train.alphas)
            f.bound = _round_up(b) if b is not None else 1.5
            where = "visual hull of the masks" if b is not None else "no point inside every mask: default"
        else:
            f.bound = 1.5
            where = "the Blender scenes' box"
        if not f.ndc():  # the inner ball is the contraction's
            notes.append(f"{'radius' if scene == 'unbounded' else 'box'} {f.bound:g} ({where})")
    notes += warp_notes
    if supports.sampling:
        s.sampling = s.resolved_sampling(f)
    if s.near is None:
        s.near = UNBOUNDED_NEAR if scene == "unbounded" else 0.0
    if s.far is None:
        s.far = UNBOUNDED_FAR if scene == "unbounded" else _round_up(float(dist.max()) + math.sqrt(3) * f.bound)
    photos = cap.photos
    if f.appearance_dim is None and not supports.appearance:
        f.appearance_dim = 0
    if f.appearance_dim is None:
        f.appearance_dim = APPEARANCE_DIM if photos else 0
        if cap.has_masks:
            log("appearance embeddings: off for a masked object capture (--appearance-dim 16 turns them on)")
    f.appearance_count = len(train) if f.appearance_dim or cfg.train.pose_refine == "on" else 0
    registry.resolve_settings(cfg, photos, len(train), log)
    if cfg.train.pose_refine == "on":
        log(f"pose refinement: a pose correction per training photo ({len(train)}), learned with the scene; "
            f"held-out photos are rendered from their given poses moved with the training rig (--pose-refine off: none)")
    if supports.unbounded or f.scene_type != "auto":
        log(f"scene: {scene} ({why}){'; ' + '; '.join(notes) if notes else ''}; near {s.near:g}, far {s.far:g}")
    if supports.sampling and scene == "unbounded" and s.sampling == "occupancy":
        rays = s.proposal_batch(cfg.train.batch_rays)
        log(f"slow: --sampling occupancy in an unbounded scene keeps every occupied cell a ray crosses, behind the "
            f"first surface too (buddha: 476 of 512 samples per ray, 137 rays per step); --sampling proposal (the "
            f"default here) places {s.field_samples} per ray and trains {rays} rays per step")
    if f.appearance_dim:
        log(f"appearance embeddings: {f.appearance_dim} per training image ({len(train)}); held-out views use the "
            f"mean embedding")
    validate(cfg)
    registry.check(cfg)
    return cfg


def wants_ndc(cfg: Config, cap: Capture, train: SceneData) -> bool:
    """Whether --warp (auto or ndc) would put the field in NDC: a method that reads it, an unbounded scene,
    a forward-facing capture."""
    return ("field.warp" in registry.method_class(cfg).reads and cfg.field.warp != "contract"
            and scene_type(cfg, cap)[0] == "unbounded" and forward_facing(train.poses))


def _resolve_warp(cfg: Config, cap: Capture, train: SceneData) -> list[str]:
    """--warp: fill in the NDC space (data/normalize.ndc_space) and its near plane, or contract; returns the
    scene line's notes saying which and why. --warp ndc on a capture that is not forward-facing, or without
    points ahead, is refused."""
    f, s = cfg.field, cfg.sampler
    spread = view_spread(train.poses)
    notes = [f"forward-facing: every camera within {spread:.0f} degrees of one direction"] \
        if forward_facing(train.poses) else []
    if "field.warp" not in registry.method_class(cfg).reads or f.scene_type != "unbounded":
        return notes
    if not wants_ndc(cfg, cap, train):
        if f.warp == "ndc":
            raise ConfigError(f"--warp ndc needs a forward-facing capture, but the cameras look up to "
                              f"{spread:.0f} degrees apart (NDC holds under {FORWARD_DEGREES:g}); use --warp contract")
        f.warp = "contract"
        return notes
    try:
        if cap.points is None:
            raise ValueError("the capture has no points")
        frame, near, extent = ndc_space(train.poses, train.cameras, transform_points(cap.points, train.transform))
    except ValueError as e:
        if f.warp == "ndc":
            raise ConfigError(f"--warp ndc needs points in front of the cameras to place its near plane ({e}); "
                              f"use --warp contract") from None
        f.warp = "contract"
        return notes + [f"contraction: no near plane for NDC ({e})"]
    f.warp, f.ndc_frame, f.ndc_near, f.ndc_extent = "ndc", frame.ravel().tolist(), near, extent
    if s.near is None:
        s.near = near
    notes.append(f"NDC of the mean camera: near plane {near:.3g} (0.9 x the 1st percentile of the points' depths), "
                 f"slopes {extent[0]:.2f} x {extent[1]:.2f} (--warp contract: the contraction)")
    return notes


def _round_up(x: float, step: float = 0.05) -> float:
    return round(math.ceil(x / step - 1e-9) * step, 6)
