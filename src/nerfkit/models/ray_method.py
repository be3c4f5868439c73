"""What the ray methods (NeRF, mip-NeRF, ngp) share: the settings each reads, their rules, the background
colour and the per-ray weighted MSE."""

from __future__ import annotations

import jax.numpy as jnp

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError


def background_color(name: str) -> jnp.ndarray:
    return jnp.ones(3, jnp.float32) if name == "white" else jnp.zeros(3, jnp.float32)


def weighted_mse(rgb: jnp.ndarray, target: jnp.ndarray, weights: jnp.ndarray | None = None) -> jnp.ndarray:
    """sum_r w_r |c_r - C_r|^2 / (3 sum_r w_r) over rays [R, 3] (w = 1 without per-ray weights [R])."""
    w = jnp.ones(target.shape[0], jnp.float32) if weights is None else weights
    return jnp.sum(w[:, None] * (rgb - target) ** 2) / (3.0 * jnp.maximum(jnp.sum(w), 1e-12))


# The settings (Config "section.field") each method reads beyond those every method reads (training
# budget, data, seed, logging): training/flags.py refuses any other one given on the command line.
RAY_SETTINGS = frozenset({
    "field.appearance_dim", "sampler.near", "sampler.far", "sampler.perturb", "train.batch_rays", "train.lr",
    "train.lr_decay_steps", "train.lr_decay_rate", "train.adam_b2", "train.precrop_steps", "train.precrop_frac",
    "train.chunk", "train.devices", "train.pose_refine"})
MLP_SETTINGS = frozenset({"field.depth", "field.width", "field.l_xyz", "field.l_dir", "field.viewdirs",
                          "sampler.n_samples", "sampler.n_importance"})
NGP_SETTINGS = frozenset({
    "field.hash_levels", "field.hash_features", "field.hash_log2_size", "field.hash_base_res",
    "field.hash_max_res", "field.hidden", "field.antialias", "field.bound", "field.scene_type", "field.warp",
    "field.ndc_frame", "field.ndc_near", "field.ndc_extent", "sampler.occ_res",
    "sampler.occ_update_every", "sampler.occ_warmup", "sampler.occ_warmup_decay", "sampler.march_steps",
    "sampler.max_samples", "sampler.sampling", "sampler.proposal_samples", "sampler.field_samples"})


def near_far(s) -> str:
    return "" if s.near is None or s.far is None else f", near {s.near:g}, far {s.far:g}"


def appearance(f) -> str:
    return f"; appearance embeddings of {f.appearance_dim}" if f.appearance_dim else ""


def samples(s) -> str:
    return f"{s.n_samples}" + (f" + {s.n_importance}" if s.n_importance else "") + " samples per ray"


def need(ok: bool, msg: str) -> None:
    """ConfigError(msg) unless ok."""
    if not ok:
        raise ConfigError(msg)


def check_mlp(cfg: Config) -> None:
    """What the MLP fields (NeRF, mip-NeRF) need: a fixed [near, far], appearance only with view directions,
    no hash-grid anti-aliasing."""
    f, s = cfg.field, cfg.sampler
    need(not f.antialias, "--antialias is for the hash-grid field (--preset ngp); the mipnerf preset anti-aliases "
                           "with its own encoding")
    need(s.near is not None and s.far is not None, "--near and --far must be set for the mlp field")
    need(f.n_appearance() == 0 or f.viewdirs, "appearance embeddings need --viewdirs with the mlp field")


def ray_unused(cfg: Config) -> dict[str, str]:
    """Settings every ray method leaves unread at their values: precrop_frac without a warm-up."""
    if cfg.train.precrop_steps == 0:
        return {"train.precrop_frac": "there is no centre-crop warm-up (--precrop-steps 0)"}
    return {}


def mlp_unused(cfg: Config) -> dict[str, str]:
    out = ray_unused(cfg)
    if not cfg.field.viewdirs:
        out["field.l_dir"] = "the colour does not depend on the view direction (--no-viewdirs)"
    return out


def mlp_surface(field, params) -> tuple:
    """surface_field of a model with one MLP: no occupancy grid (every point is a candidate)."""
    return field, params, None, 0.0


