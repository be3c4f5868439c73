"""The hash-grid field (Instant-NGP) sampled by marching an occupancy grid (NGPModel); proposal
sampling for unbounded scenes is ngp_proposal.py."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.core.config import Config
from nerfkit.data.capture import scene_type
from nerfkit.fields.ngp import HashGridField
from nerfkit.models.base import Supports
from nerfkit.models.ray_method import (
    NGP_SETTINGS,
    RAY_SETTINGS,
    appearance,
    background_color,
    near_far,
    need,
    ray_unused,
    weighted_mse,
)
from nerfkit.rays.frustum import footprint_std
from nerfkit.render.volume import packed_composite, packed_compositing_weights
from nerfkit.sampling import occupancy


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
    supports = Supports(family="marching", parallel="samples", step_metrics=True, bake=True, unbounded=True,
                        sampling=True, pose_refine=True)
    title = "hash-grid (ngp)"
    loss_name = "MSE"
    reads = RAY_SETTINGS | NGP_SETTINGS

    @staticmethod
    def describe(cfg: Config) -> str:
        f, s = cfg.field, cfg.sampler
        scene = f"{f.scene_type} scene, " if f.scene_type != "auto" else ""
        box = "" if f.bound is None else (f"inner ball {f.bound:g}, " if f.scene_type == "unbounded" else
                                          f"box {f.bound:g}, ")
        if f.ndc():
            box = f"NDC of the mean camera from depth {f.ndc_near:.3g}, "
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
                f"; {scene}{box}{sampling}{near_far(s)}{appearance(f)}")

    @staticmethod
    def check(cfg: Config) -> None:
        f, s = cfg.field, cfg.sampler
        need(f.bound is None or f.bound > 0, f"--bound must be positive (got {f.bound})")
        need(1 <= f.hash_levels and 1 <= f.hash_features and 10 <= f.hash_log2_size <= 24,
              "--hash-levels, --hash-features must be >= 1 and --hash-log2-size in [10, 24]")
        need(2 <= f.hash_base_res <= f.hash_max_res, "need 2 <= --hash-base-res <= --hash-max-res")
        need(s.occ_res >= 2 and s.occ_update_every >= 1 and s.march_steps >= 2,
              "need --occ-res >= 2, --occ-update-every >= 1, --march-steps >= 2")
        need(s.max_samples >= s.march_steps, f"--max-samples must be >= --march-steps ({s.march_steps})")
        need(s.proposal_samples >= 4 and s.field_samples >= 2,
             "need --proposal-samples >= 4 and --field-samples >= 2")

    @staticmethod
    def unused(cfg: Config, capture=None) -> dict[str, str]:
        s = cfg.sampler
        out = ray_unused(cfg)
        if s.occ_warmup == 0:
            out["sampler.occ_warmup_decay"] = "there is no occupancy warm-up (--occ-warmup 0)"
        if s.sampling != "auto" or capture is not None:
            sampling = s.sampling
            if sampling == "auto":  # decided by the scene (training/resolve.py): proposal for unbounded ones
                sampling = "proposal" if scene_type(cfg.field.scene_type, capture)[0] == "unbounded" else "occupancy"
            if sampling == "occupancy":
                why = (f"the occupancy grid places the samples here (--sampling {s.sampling}"
                       f"{'' if s.sampling != 'auto' else ': a bounded scene'}); --sampling proposal reads it")
                out["sampler.proposal_samples"] = out["sampler.field_samples"] = why
        if cfg.field.scene_type == "bounded" or (
                capture is not None and scene_type(cfg.field.scene_type, capture)[0] == "bounded"):
            out["field.warp"] = "the scene is bounded (a box); --warp maps unbounded scenes into the grid"
        return out

    def surface_field(self, params, aux) -> tuple:
        """As NeRFModel.surface_field: the hash-grid field, and its occupancy grid as occupied(x)."""
        field = self.field
        cell = self.occ.cell_size * (field.radius if field.unbounded else 1.0)

        def occupied(x):
            return occupancy.query_occupancy(aux, field.to_grid(x), self.occ)

        return field, params["field"], occupied, cell

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
        # the grid stores sigma times the stretch of the step there (HashGridField.stretch).
        self.occ = occupancy.OccupancyConfig(resolution=s.occ_res, bound=self.field.grid_bound,
                                             threshold=0.01 / self.step_size, warmup_decay=s.occ_warmup_decay)
        self.background = background_color(cfg.data.background)
        # Sample budget per ray of render_rays(train=False), the one-pass renderer (render/chunked.Renderer): only
        # tests and references use it (images are rendered by render/wavefront.WavefrontRenderer); rays that overflow
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
        return sigma * self.field.stretch(y)

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
