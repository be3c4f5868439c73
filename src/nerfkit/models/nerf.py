"""A renderable scene model: field(s) + sampler + volume renderer.

`MipNeRFModel` is mip-NeRF: cones instead of rays, one MLP on integrated encodings of conical
frustums, queried on stratified intervals then on intervals resampled from its blurred weights.
`NeRFModel` is the original NeRF pipeline: stratified samples through a coarse field,
and optionally inverse-CDF samples from the coarse weights through a fine field
(hierarchical sampling). Every model exposes the same small interface, which the
trainer, evaluation and rendering code use without knowing which field is inside:

    init(key) -> (params, aux)            trainable params, non-trainable state
    render_rays(params, aux, o, d, key, train, image_idx=None, radii=None) -> {"rgb", "depth", "opacity", ...}
        (image_idx [R]: the training image of each ray, for appearance embeddings; None: mean;
         radii [R]: each ray's cone radius per unit z-depth, frustum.pixel_base_radius, for the
         anti-aliased models; None: thin rays)
    losses(out, target, weights=None) -> (loss, {"mse": ...})
    update_aux(params, aux, step, key) -> aux   (e.g. an occupancy grid; no-op here)

Method families that are not radiance fields (Gaussian splats: splat/method.py) render whole
views, not rays: build_model returns their own model object, and the trainer, the renderer
factory and the checkpoint loader hand it the optimiser, the training step and the renderer
(a model with `make_train_step` owns them; see splat/method.py for that interface).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.core.config import Config
from nerfkit.fields.mlp import MLPField
from nerfkit.fields.ngp import HashGridField
from nerfkit.models.base import Supports
from nerfkit.rays.coord import radial_stretch
from nerfkit.rays.frustum import conical_frustum_to_gaussian, footprint_std
from nerfkit.render.volume import (
    composite,
    compositing_weights,
    packed_composite,
    packed_compositing_weights,
    volume_render,
)
from nerfkit.sampling import occupancy
from nerfkit.sampling.intervals import (
    blur_weights,
    midpoints,
    sample_pdf,
    stratified_edges,
    stratified_samples,
)


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
    "train.chunk", "train.devices"})
MLP_SETTINGS = frozenset({"field.depth", "field.width", "field.l_xyz", "field.l_dir", "field.viewdirs",
                          "sampler.n_samples", "sampler.n_importance"})
NGP_SETTINGS = frozenset({
    "field.hash_levels", "field.hash_features", "field.hash_log2_size", "field.hash_base_res",
    "field.hash_max_res", "field.hidden", "field.antialias", "field.bound", "field.scene_type", "sampler.occ_res",
    "sampler.occ_update_every", "sampler.occ_warmup", "sampler.occ_warmup_decay", "sampler.march_steps",
    "sampler.max_samples", "sampler.sampling", "sampler.proposal_samples", "sampler.field_samples"})


def _near_far(s) -> str:
    return "" if s.near is None or s.far is None else f", near {s.near:g}, far {s.far:g}"


def _appearance(f) -> str:
    return f"; appearance embeddings of {f.appearance_dim}" if f.appearance_dim else ""


def _samples(s) -> str:
    return f"{s.n_samples}" + (f" + {s.n_importance}" if s.n_importance else "") + " samples per ray"


class NeRFModel:
    supports = Supports(family="rays", parallel="rays")
    title = "NeRF MLP"
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
                f"{_samples(s)}{' (coarse + fine)' if s.n_importance else ''}{_near_far(s)}{_appearance(f)}")

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


class MipNeRFModel:
    """mip-NeRF (Barron et al. 2021): a cone of radius t |d| r per pixel (r = radii, per unit z-depth),
    cut into conical frustums [t_k, t_k+1], each encoded by the integrated positional encoding of its
    Gaussian (frustum.py, encoding/integrated.py) and shaded by one MLP. Pass 1: n_samples stratified
    intervals over [near, far]; pass 2: n_importance + 1 edges drawn from the blurred coarse weights
    (sampling.blur_weights, padding 0.01), replacing the coarse ones. Loss: fine MSE + 0.1 coarse MSE,
    both weighted per ray on multiscale data (pixel area)."""

    supports = Supports(family="rays", parallel="rays", antialias=True)
    title = "mip-NeRF"
    reads = RAY_SETTINGS | MLP_SETTINGS
    RESAMPLE_PADDING = 0.01
    COARSE_LOSS_MULT = 0.1

    @staticmethod
    def describe(cfg: Config) -> str:
        f, s = cfg.field, cfg.sampler
        enc = f"integrated PE of cones L_xyz={f.l_xyz}" + (f", L_dir={f.l_dir}" if f.viewdirs else "")
        return (f"mip-NeRF: MLP D={f.depth} W={f.width}, {enc}{'' if f.viewdirs else ', no view directions'}; "
                f"{_samples(s)}{_near_far(s)}{_appearance(f)}")

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.rays_per_step = cfg.train.batch_rays  # rays drawn per training step
        self.field = MLPField(cfg.field)
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


class NGPModel:
    """Hash-grid field with occupancy-grid empty-space skipping (Instant-NGP style).

    Bounded scenes: rays march through the box [-bound, bound]^3 at a fixed step
    (2 sqrt(3) bound / march_steps, in t units). Unbounded scenes: march_steps candidates
    evenly spaced in s = g(t) (coord.spacing: linear inside the inner ball of radius
    bound, disparity beyond), the occupancy grid over the contracted cube [-2, 2]^3, and
    a random background colour per ray while training (so the field, not the background,
    explains every pixel). Only samples in occupied cells are kept; the kept samples of all
    rays are packed into a fixed budget (static shapes). While training, `batch_rays` rays
    are drawn and the rays whose samples all fit in `max_samples` are rendered and scored
    ("complete" rays), so the number of rays per step adapts to keep the budget full.
    Weights stop once transmittance drops below 1e-4. The occupancy grid (aux) is refreshed
    every `occ_update_every` steps inside the jitted step.
    """

    MIN_TRANSMITTANCE = 1e-4
    # Data parallelism (parallel.py): split the packed samples, not the rays, over the devices. Splitting
    # the rays makes XLA partition the packing (a prefix sum and scatter over all candidates of all rays):
    # measured 8.9 s per step on 2 forced CPU devices against 0.08 s when only the samples are split.
    supports = Supports(family="marching", parallel="samples", step_metrics=True, bake=True)
    title = "hash-grid (ngp)"
    reads = RAY_SETTINGS | NGP_SETTINGS

    @staticmethod
    def describe(cfg: Config) -> str:
        f, s = cfg.field, cfg.sampler
        scene = f"{f.scene_type} scene, " if f.scene_type != "auto" else ""
        box = "" if f.bound is None else (f"inner ball {f.bound:g}, " if f.scene_type == "unbounded" else
                                          f"box {f.bound:g}, ")
        if s.resolved_sampling(f) == "proposal":
            rays = s.proposal_batch(cfg.train.batch_rays)
            first, second, field = s.proposal_counts()
            sampling = (f"proposal sampling: {first} + {second} proposal and {field} field samples per ray, {rays} "
                        f"rays per step")
        else:
            sampling = (f"occupancy grid {s.occ_res}^3, {s.march_steps} march steps, up to {s.max_samples} samples "
                        f"per step")
        return (f"ngp: hash grid {f.hash_levels} levels x {f.hash_features} features, 2^{f.hash_log2_size} entries, "
                f"{f.hash_base_res}-{f.hash_max_res} cells; MLPs {f.hidden} wide{', anti-aliased' if f.antialias else ''}"
                f"; {scene}{box}{sampling}{_near_far(s)}{_appearance(f)}")

    @staticmethod
    def shard_samples(x):
        """Identity; the training step of a multi-device run sets it to parallel.shard_rays on its mesh."""
        return x

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.rays_per_step = cfg.train.batch_rays  # drawn per step; those whose samples fit max_samples train
        self.field = HashGridField(cfg.field)
        s = cfg.sampler
        self.unbounded = self.field.unbounded
        radius = self.field.radius
        # t-step inside the box, or inside the inner ball (s spans ~[0, 2] over march_steps).
        self.step_size = (2.0 * radius if self.unbounded else 2.0 * 3**0.5 * radius) / s.march_steps
        # A cell is worth sampling if one marching step through it has optical depth
        # sigma * step >= 0.01 (instant-ngp's minimum optical thickness); in contracted space
        # the grid stores sigma times the stretch of the step there (coord.radial_stretch).
        self.occ = occupancy.OccupancyConfig(resolution=s.occ_res, bound=self.field.grid_bound,
                                             threshold=0.01 / self.step_size, warmup_decay=s.occ_warmup_decay)
        self.background = background_color(cfg.data.background)
        # Sample budget per ray of render_rays(train=False), the one-pass renderer (inference.Renderer): only
        # tests and references use it (images are rendered by inference.WavefrontRenderer); rays that overflow
        # are re-queued, so it changes the speed, not the result.
        self.eval_samples_per_ray = 48
        # Unresolved (no data seen): the defaults of resolve.py.
        self.near = s.near if s.near is not None else (0.05 if self.unbounded else 0.0)
        self.far = s.far if s.far is not None else 1e4

    def init(self, key):
        return {"field": self.field.init(key)}, occupancy.init_occupancy(self.occ)

    def occupancy_density(self, params, y):
        """What the occupancy grid stores at grid points y [M, 3] (see __init__)."""
        sigma = self.field.density_grid(params["field"], y)
        return sigma * radial_stretch(y) if self.unbounded else sigma

    def update_aux(self, params, aux, step, key):
        s = self.cfg.sampler

        def update(a):
            return occupancy.update_occupancy(a, lambda y: self.occupancy_density(params, y), key, step,
                                              self.occ, warmup_steps=s.occ_warmup)

        return jax.lax.cond(step % s.occ_update_every == 0, update, lambda a: a, aux)

    def candidates(self, o, d, key=None, index=None):
        """Candidate intervals of rays o, d [R, 3]: t_start, t_end, cand, [R, march_steps] or
        shaped like `index` (int [R, W], the candidates to make; see occupancy.box_candidates)."""
        s = self.cfg.sampler
        if self.unbounded:
            return occupancy.contracted_candidates(o.shape[0], self.near, self.far, self.field.radius,
                                                   s.march_steps, key, index)
        return occupancy.box_candidates(o, d, self.near, self.far, self.field.radius, self.step_size,
                                        s.march_steps, key, index)

    def march(self, aux, o, d, budget: int, key=None) -> dict:
        """Packed samples of rays o, d [R, 3] (occupancy.pack_candidates)."""
        t0, t1, cand = self.candidates(o, d, key)
        return occupancy.pack_candidates(aux, o, d, t0, t1, cand, self.occ, budget, to_grid=self.field.to_grid)

    def sample_scale(self, t, dir_norm, radii):
        """Footprint std [S] of samples at t [S] on rays with |d| [S] and cone radii [S] (frustum.footprint_std)
        for the anti-aliased field; None (all levels at full weight) otherwise or without radii."""
        if not self.cfg.field.antialias or radii is None:
            return None
        return footprint_std(t, dir_norm, radii)

    def render_rays(self, params, aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        """Render rays o, d [R, 3] (cones of radii [R] for the anti-aliased field, see sample_scale); also
        returns complete [R] (rays whose samples all fit the budget; the others must be rendered again)
        and the number of samples used."""
        s = self.cfg.sampler
        n = o.shape[0]
        budget = s.max_samples if train else n * self.eval_samples_per_ray
        k_march, k_bg = jax.random.split(key)
        m = self.march(aux, o, d, budget, k_march if (train and s.perturb) else None)
        ray = m["ray_idx"]
        valid = m["valid"] & m["complete"][ray]
        dir_norm = jnp.linalg.norm(d, axis=-1)
        t_mid = 0.5 * (m["t_start"] + m["t_end"])
        x = o[ray] + t_mid[:, None] * d[ray]
        viewdir = d[ray] / dir_norm[ray][:, None]
        emb = self.field.embedding(params["field"], image_idx)
        if emb is not None:
            emb = emb[ray] if image_idx is not None else emb
        footprint = self.sample_scale(t_mid, dir_norm[ray], None if radii is None else radii[ray])
        x, viewdir, footprint = self.shard_samples((x, viewdir, footprint))
        rgb, sigma = self.field(params["field"], x, viewdir, emb, footprint=footprint)
        delta = (m["t_end"] - m["t_start"]) * dir_norm[ray]
        w = packed_compositing_weights(sigma, delta, ray, valid, self.MIN_TRANSMITTANCE)
        bg = jax.random.uniform(k_bg, (n, 3)) if (train and self.unbounded) else self.background
        out = packed_composite(w, rgb, t_mid, ray, n, bg, self.far)
        out["complete"] = m["complete"]
        out["n_samples"] = jnp.sum(valid)
        return out

    @staticmethod
    def losses(out: dict, target: jnp.ndarray, weights: jnp.ndarray | None = None):
        """MSE over the complete rays (weighted by per-ray weights [R] when given)."""
        mask = out["complete"].astype(jnp.float32)
        mse = weighted_mse(out["rgb"], target, mask if weights is None else mask * weights)
        return mse, {"mse": mse}

    @staticmethod
    def step_metrics(out: dict) -> dict:
        rays = jnp.sum(out["complete"])
        return {"rays": rays, "samples_per_ray": out["n_samples"] / jnp.maximum(rays, 1)}
