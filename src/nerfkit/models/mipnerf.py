"""mip-NeRF (Barron et al. 2021): cones instead of rays, one MLP on integrated encodings of conical
frustums, queried on stratified intervals then on intervals resampled from its blurred weights."""

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
    need,
    samples,
    weighted_mse,
)
from nerfkit.rays.frustum import conical_frustum_to_gaussian
from nerfkit.render.volume import composite, compositing_weights
from nerfkit.sampling.intervals import blur_weights, sample_pdf, stratified_edges


class MipNeRFModel:
    """mip-NeRF (Barron et al. 2021): a cone of radius t |d| r per pixel (r = radii, per unit z-depth),
    cut into conical frustums [t_k, t_k+1], each encoded by the integrated positional encoding of its
    Gaussian (frustum.py, encoding/integrated.py) and shaded by one MLP. Pass 1: n_samples stratified
    intervals over [near, far]; pass 2: n_importance + 1 edges drawn from the blurred coarse weights
    (sampling.blur_weights, padding 0.01), replacing the coarse ones. Loss: fine MSE + 0.1 coarse MSE,
    both weighted per ray on multiscale data (pixel area)."""

    supports = Supports(family="rays", parallel="rays", pose_refine=True)
    title = "mip-NeRF"
    loss_name = "MSE"
    reads = RAY_SETTINGS | MLP_SETTINGS
    RESAMPLE_PADDING = 0.01
    COARSE_LOSS_MULT = 0.1

    @staticmethod
    def describe(cfg: Config) -> str:
        f, s = cfg.field, cfg.sampler
        enc = f"integrated PE of cones L_xyz={f.l_xyz}" + (f", L_dir={f.l_dir}" if f.viewdirs else "")
        return (f"mip-NeRF: MLP D={f.depth} W={f.width}, {enc}{'' if f.viewdirs else ', no view directions'}; "
                f"{samples(s)}{near_far(s)}{appearance(f)}")

    @staticmethod
    def check(cfg: Config) -> None:
        check_mlp(cfg)
        need(cfg.field.pe, "--no-pe does not apply to mipnerf (its encoding is the integrated one)")

    @staticmethod
    def unused(cfg: Config, capture=None) -> dict[str, str]:
        return mlp_unused(cfg)

    def surface_field(self, params, aux) -> tuple:
        """As NeRFModel.surface_field: the one MLP at points (a Gaussian of zero variance: IPE = PE)."""
        return mlp_surface(self.field, params["field"])

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.rays_per_step = cfg.train.batch_rays  # rays drawn per training step
        self.field = MLPField(cfg.field, integrated=True)
        self.background = background_color(cfg.data.background)

    def init(self, key):
        return {"field": self.field.init(key)}, {}

    def update_aux(self, params, aux, step, key):
        return aux

    def _shade(self, params, o, d, t, radii, image_idx) -> dict:
        """Composite of the frustums between edges t [R, N + 1]; also returns their weights [R, N] and the edges."""
        mean, var = conical_frustum_to_gaussian(o, d, t[:, :-1], t[:, 1:], radii)
        norm = jnp.linalg.norm(d, axis=-1)
        emb = self.field.embedding(params, image_idx)
        rgb, sigma = self.field(params, mean, (d / norm[:, None])[:, None, :],
                                None if emb is None else emb[:, None, :], footprint=var)
        w = compositing_weights(sigma, (t[:, 1:] - t[:, :-1]) * norm[:, None])
        out = composite(w, rgb, 0.5 * (t[:, 1:] + t[:, :-1]), self.background)
        out["weights"], out["edges"] = w, t
        return out

    def render_rays(self, params, aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        """Render cones o, d [R, 3] of radii [R] (None: 0, thin rays, the IPE becomes the PE). Returns rgb
        [R, 3], depth, opacity, depth_normalized [R] and "coarse" (the first pass's outputs)."""
        s = self.cfg.sampler
        radii = jnp.zeros(o.shape[0], jnp.float32) if radii is None else radii
        k_strat, k_pdf = jax.random.split(key)
        perturb = train and s.perturb
        t = stratified_edges(k_strat, o.shape[0], s.n_samples, s.near, s.far, perturb)
        coarse = self._shade(params["field"], o, d, t, radii, image_idx)
        if s.n_importance == 0:
            return coarse
        t_fine = sample_pdf(k_pdf, t, blur_weights(coarse["weights"], self.RESAMPLE_PADDING), s.n_importance + 1,
                            deterministic=not perturb)
        fine = self._shade(params["field"], o, d, t_fine, radii, image_idx)
        fine["coarse"] = coarse
        return fine

    @classmethod
    def losses(cls, out: dict, target: jnp.ndarray, weights: jnp.ndarray | None = None):
        """Fine MSE + 0.1 x coarse MSE (weighted_mse with per-ray weights [R] when given)."""
        mse = weighted_mse(out["rgb"], target, weights)
        loss = mse
        if "coarse" in out:
            loss = loss + cls.COARSE_LOSS_MULT * weighted_mse(out["coarse"]["rgb"], target, weights)
        return loss, {"mse": mse}
