"""A renderable scene model: field(s) + sampler + volume renderer.

`NeRFModel` is the original NeRF pipeline: stratified samples through a coarse field,
and optionally inverse-CDF samples from the coarse weights through a fine field
(hierarchical sampling). Every model exposes the same small interface, which the
trainer, evaluation and rendering code use without knowing which field is inside:

    init(key) -> (params, aux)            trainable params, non-trainable state
    render_rays(params, aux, o, d, key, train) -> {"rgb", "depth", "opacity", ...}
    losses(out, target) -> (loss, {"mse": ...})
    update_aux(params, aux, step, key) -> aux   (e.g. an occupancy grid; no-op here)
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.config import Config
from nerfkit.fields.mlp import MLPField
from nerfkit.render import volume_render
from nerfkit.sampling import midpoints, sample_pdf, stratified_samples


def background_color(name: str) -> jnp.ndarray:
    return jnp.ones(3, jnp.float32) if name == "white" else jnp.zeros(3, jnp.float32)


class NeRFModel:
    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.coarse = MLPField(cfg.field)
        self.fine = MLPField(cfg.field) if cfg.sampler.n_importance > 0 else None
        self.background = background_color(cfg.data.background)

    def init(self, key):
        k1, k2 = jax.random.split(key)
        params = {"coarse": self.coarse.init(k1)}
        if self.fine is not None:
            params["fine"] = self.fine.init(k2)
        return params, {}

    def update_aux(self, params, aux, step, key):
        return aux

    def _shade(self, field, params, o, d, viewdir, t, last_interval):
        x = o[:, None, :] + t[..., None] * d[:, None, :]  # [R, N, 3]
        rgb, sigma = field(params, x, viewdir[:, None, :])
        return volume_render(sigma, rgb, t, jnp.linalg.norm(d, axis=-1), last_interval, self.background)

    def render_rays(self, params, aux, o, d, key, train: bool) -> dict:
        """Render rays o, d [R, 3]. Returns rgb [R, 3], depth, opacity, depth_normalized [R]
        (and "coarse": the coarse pass's outputs when hierarchical sampling is on)."""
        s = self.cfg.sampler
        k_strat, k_pdf = jax.random.split(key)
        viewdir = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
        t = stratified_samples(k_strat, o.shape[0], s.n_samples, s.near, s.far, perturb=train and s.perturb)
        bin_width = (s.far - s.near) / s.n_samples
        out = self._shade(self.coarse, params["coarse"], o, d, viewdir, t, bin_width)
        if self.fine is None:
            return out
        # Fine pass: importance samples from the coarse weights on the interior bins
        # (edges at coarse midpoints), merged with the coarse samples.
        t_fine = sample_pdf(k_pdf, midpoints(t), out["weights"][..., 1:-1], s.n_importance,
                            deterministic=not (train and s.perturb))
        t_all = jnp.sort(jnp.concatenate([t, t_fine], axis=-1), axis=-1)
        fine = self._shade(self.fine, params["fine"], o, d, viewdir, t_all,
                           (s.far - s.near) / (s.n_samples + s.n_importance))
        fine["coarse"] = out
        return fine

    @staticmethod
    def losses(out: dict, target: jnp.ndarray):
        """MSE of the rendered colour (plus the coarse pass's MSE, as in NeRF)."""
        mse = jnp.mean((out["rgb"] - target) ** 2)
        loss = mse
        if "coarse" in out:
            loss = loss + jnp.mean((out["coarse"]["rgb"] - target) ** 2)
        return loss, {"mse": mse}


def build_model(cfg: Config):
    """The model for `cfg.field.kind`."""
    if cfg.field.kind == "mlp":
        return NeRFModel(cfg)
    if cfg.field.kind == "ngp":
        from nerfkit.ngp import NGPModel  # noqa: PLC0415 - optional fast path

        return NGPModel(cfg)
    raise ValueError(f"unknown field kind {cfg.field.kind!r}")
