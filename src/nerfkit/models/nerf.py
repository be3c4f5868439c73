"""NeRF (Mildenhall et al. 2020): stratified samples through a coarse MLP field and, optionally,
inverse-CDF samples from the coarse weights through a fine field (hierarchical sampling).

Every ray method (this one, mipnerf.py, ngp.py) exposes the same small interface, which the trainer,
evaluation and rendering code use without knowing which field is inside (models/base.py):

    init(key) -> (params, aux)            trainable params, non-trainable state
    render_rays(params, aux, o, d, key, train, image_idx=None, radii=None) -> {"rgb", "depth", "opacity", ...}
        (image_idx [R]: the training image of each ray, for appearance embeddings; None: mean;
         radii [R]: each ray's cone radius per unit z-depth, frustum.pixel_base_radius, for the
         anti-aliased models; None: thin rays)
    losses(out, target, weights=None) -> (loss, {"mse": ...})
    update_aux(params, aux, step, key) -> aux   (e.g. an occupancy grid; no-op here)
    surface_field(params, aux) -> the field that meshes and grids sample
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.core.config import Config
from nerfkit.fields.mlp import MLPField
from nerfkit.models.base import Supports
from nerfkit.models.ray_method import (
    MLP_SETTINGS,
    RAY_SETTINGS,
    appearance,
    background_color,
    check_mlp,
    mlp_surface,
    mlp_unused,
    near_far,
    samples,
    weighted_mse,
)
from nerfkit.render.volume import volume_render
from nerfkit.sampling.intervals import midpoints, sample_pdf, stratified_samples


class NeRFModel:
    supports = Supports(family="rays", parallel="rays", pose_refine=True)
    title = "NeRF MLP"
    loss_name = "MSE"
    reads = RAY_SETTINGS | MLP_SETTINGS | {"field.pe"}

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.rays_per_step = cfg.train.batch_rays  # rays drawn per training step
        self.coarse = MLPField(cfg.field)
        self.fine = MLPField(cfg.field) if cfg.sampler.n_importance > 0 else None
        self.background = background_color(cfg.data.background)

    @staticmethod
    def describe(cfg: Config) -> str:
        """One line naming the model with the settings it reads (and only those)."""
        f, s = cfg.field, cfg.sampler
        enc = (f"PE L_xyz={f.l_xyz}" + (f", L_dir={f.l_dir}" if f.viewdirs else "")) if f.pe else "no PE (raw x, d)"
        return (f"NeRF MLP D={f.depth} W={f.width}, {enc}{'' if f.viewdirs else ', no view directions'}; "
                f"{samples(s)}{' (coarse + fine)' if s.n_importance else ''}{near_far(s)}{appearance(f)}")

    @staticmethod
    def check(cfg: Config) -> None:
        check_mlp(cfg)

    @staticmethod
    def unused(cfg: Config, capture=None) -> dict[str, str]:
        out = mlp_unused(cfg)
        if not cfg.field.pe:
            out["field.l_xyz"] = out["field.l_dir"] = "positional encoding is off (--no-pe)"
        return out

    def surface_field(self, params, aux) -> tuple:
        """(field, its params, occupied(x) or None, occupancy cell size): the density and colour that meshes
        and grids sample (export/grid.py); here the fine MLP when there is one."""
        key = "fine" if self.fine is not None else "coarse"
        return mlp_surface(getattr(self, key), params[key])

    def init(self, key):
        k1, k2 = jax.random.split(key)
        params = {"coarse": self.coarse.init(k1)}
        if self.fine is not None:
            params["fine"] = self.fine.init(k2)
        return params, {}

    def update_aux(self, params, aux, step, key):
        return aux

    def _shade(self, field, params, o, d, viewdir, t, last_interval, image_idx):
        x = o[:, None, :] + t[..., None] * d[:, None, :]  # [R, N, 3]
        emb = field.embedding(params, image_idx)
        rgb, sigma = field(params, x, viewdir[:, None, :], None if emb is None else emb[:, None, :])
        return volume_render(sigma, rgb, t, jnp.linalg.norm(d, axis=-1), last_interval, self.background)

    def render_rays(self, params, aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        """Render rays o, d [R, 3] (thin rays: radii is ignored). Returns rgb [R, 3], depth, opacity,
        depth_normalized [R] (and "coarse": the coarse pass's outputs when hierarchical sampling is on)."""
        s = self.cfg.sampler
        k_strat, k_pdf = jax.random.split(key)
        viewdir = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
        t = stratified_samples(k_strat, o.shape[0], s.n_samples, s.near, s.far, perturb=train and s.perturb)
        bin_width = (s.far - s.near) / s.n_samples
        out = self._shade(self.coarse, params["coarse"], o, d, viewdir, t, bin_width, image_idx)
        if self.fine is None:
            return out
        # Fine pass: importance samples from the coarse weights on the interior bins
        # (edges at coarse midpoints), merged with the coarse samples.
        t_fine = sample_pdf(k_pdf, midpoints(t), out["weights"][..., 1:-1], s.n_importance,
                            deterministic=not (train and s.perturb))
        t_all = jnp.sort(jnp.concatenate([t, t_fine], axis=-1), axis=-1)
        fine = self._shade(self.fine, params["fine"], o, d, viewdir, t_all,
                           (s.far - s.near) / (s.n_samples + s.n_importance), image_idx)
        fine["coarse"] = out
        return fine

    @staticmethod
    def losses(out: dict, target: jnp.ndarray, weights: jnp.ndarray | None = None):
        """MSE of the rendered colour (plus the coarse pass's MSE, as in NeRF), weighted per ray
        (weighted_mse) when weights [R] are given."""
        mse = weighted_mse(out["rgb"], target, weights)
        loss = mse
        if "coarse" in out:
            loss = loss + weighted_mse(out["coarse"]["rgb"], target, weights)
        return loss, {"mse": mse}
