"""The hash-grid field with proposal sampling (`--sampling proposal`, the default for unbounded scenes):
nerfacto's sampler in front of nerfkit's ngp field.

Why: in an unbounded scene (a room, a garden) the occupancy grid cannot say what a ray sees first: every
surface behind the first one, and the air the grid has not yet carved, stays occupied: on buddha a ray kept
476 of its 512 march candidates and a 65,536-sample step held 137 rays (2 minutes at --downscale 4).
Proposal sampling (sampling/proposal.py) puts a fixed, small number of samples per ray where small density
fields say the ray's weight is, in front of and at the first surface:

    round 0    uniform_edges: proposal_samples (64) intervals evenly spaced in s = coord.spacing(t)
               (linear inside the inner ball, disparity beyond) over [near, far]
    round 1    proposal field 1 (5 levels, 16-128 cells) -> weights -> resample_edges: proposal_samples / 2
    round 2    proposal field 2 (5 levels, 16-256 cells) -> weights -> resample_edges: field_samples (32)
    field      the ngp field (fields/ngp.py) at the midpoints of those field_samples intervals, composited
               as in render/volume.py (a random background per ray while training, as the marching model)

Loss: the colour MSE + INTERLEVEL_MULT x interlevel_loss (the proposals learn to cover the field's weights)
+ DISTORTION_MULT x distortion_loss (nerfacto's 1.0 and 0.002). Every ray costs the same, so a step draws
--max-samples / --field-samples rays (2048; SamplerConfig.proposal_batch) and renders them all; they split
over devices like the MLP fields' rays. The weights are annealed while the proposals are young (ANNEAL_STEPS)
and every density starts low (INIT_OPTICAL_DEPTH): with the hash grid's usual start (sigma ~ 1 per unit, the
inner ball ~9 units across), on a 160 px room-like procedural capture (3 minutes, 128 + 64 proposal samples)
the proposals piled every sample in front of the cameras and the field painted each photo there: 13.2 dB
held out at 4096 rays per step, against 21.3 dB from the low start at 2048.

The occupancy grid is still kept up to date in aux (as the marching model does: mesh, point-cloud and bake
exports find the scene's occupied cells with it); rendering does not use it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.config import Config
from nerfkit.fields.proposal import ProposalField, ProposalFieldConfig
from nerfkit.models.base import Supports
from nerfkit.models.ngp import NGPModel
from nerfkit.models.ray_method import weighted_mse
from nerfkit.rays.coord import spacing_inverse
from nerfkit.render.volume import composite, compositing_weights
from nerfkit.sampling.proposal import distortion_loss, interlevel_loss, resample_edges, uniform_edges

INTERLEVEL_MULT = 1.0
DISTORTION_MULT = 0.002
# The proposal weights are raised to the power a(step) = 10 x / (9 x + 1), x = min(step / ANNEAL_STEPS, 1), before
# resampling (nerfacto's annealing, over 1000 of its 30k steps; a 10-minute CPU run takes ~2k): from uniform
# sampling while the young proposals know nothing (a = 0) to their full weights (a = 1).
ANNEAL_STEPS = 250
INIT_OPTICAL_DEPTH = 1.0
ANNEAL_SLOPE = 10.0
# The proposal fields of the two rounds (nerfacto's: 5 levels, finest 128 then 256 cells, 16 wide).
PROPOSAL_FIELDS = (ProposalFieldConfig(max_res=128), ProposalFieldConfig(max_res=256))


class ProposalNGPModel(NGPModel):
    """NGPModel's field sampled by proposal fields (module docstring). Same interface as NGPModel, but a
    plain RayModel: render_rays renders every ray (no packing, no incomplete rays)."""

    supports = Supports(family="rays", parallel="rays", step_metrics=True, bake=True, unbounded=True, sampling=True,
                        pose_refine=True)

    def __init__(self, cfg: Config):
        super().__init__(cfg)
        s = cfg.sampler
        self.proposals = [ProposalField(c, self.field.to_grid, self.field.grid_bound) for c in PROPOSAL_FIELDS]
        self.counts = s.proposal_counts()
        # The field's samples per step are --max-samples, as for the marching model: here every ray takes
        # field_samples, so a step draws max_samples / field_samples rays (at most --batch-rays).
        self.rays_per_step = s.proposal_batch(cfg.train.batch_rays)

    def _init_parts(self, key):
        """Field and proposal parameters, every density starting at INIT_OPTICAL_DEPTH / (2 R): a young ray
        crossing the inner ball (2 R long) sees optical depth INIT_OPTICAL_DEPTH, so its weight spreads
        over the scene instead of piling up in front of the camera."""
        k_field, *k_prop = jax.random.split(key, 1 + len(self.proposals))
        params, aux = super().init(k_field)
        params["proposal"] = [p.init(k) for p, k in zip(self.proposals, k_prop)]
        log_sigma0 = float(np.log(INIT_OPTICAL_DEPTH / (2.0 * self.field.radius)))
        last = params["field"]["density"][-1]
        params["field"]["density"][-1] = dict(last, b=last["b"].at[0].set(log_sigma0))
        for p in params["proposal"]:
            p["b2"] = jnp.full_like(p["b2"], log_sigma0)
        return params, aux

    def init(self, key):
        params, aux = self._init_parts(key)
        return params, dict(aux, step=jnp.zeros((), jnp.int32))

    def update_aux(self, params, aux, step, key):
        """The occupancy grid's refresh (NGPModel.update_aux) and the step, which sets the annealing."""
        grid = super().update_aux(params, {k: v for k, v in aux.items() if k != "step"}, step, key)
        return dict(grid, step=jnp.asarray(step, jnp.int32))

    @staticmethod
    def anneal(step) -> jnp.ndarray:
        """The exponent a(step) of the proposal weights (see ANNEAL_STEPS)."""
        x = jnp.minimum(jnp.asarray(step, jnp.float32) / ANNEAL_STEPS, 1.0)
        return ANNEAL_SLOPE * x / ((ANNEAL_SLOPE - 1.0) * x + 1.0)

    def sample(self, params, o, d, key, train: bool, anneal=1.0):
        """The proposal rounds for rays o, d [R, 3]: the field's edges [R, field_samples + 1] in s, and each
        round's (edges, weights) (the interlevel loss compares them with the field's weights); the weights
        are resampled raised to the power `anneal`. The rays reach the proposal networks without their
        gradient: they only place the field's samples, so pose corrections (--pose-refine) learn from the
        field's colours, and the step skips a backward pass through every proposal round's positions."""
        o, d = jax.lax.stop_gradient(o), jax.lax.stop_gradient(d)
        n = o.shape[0]
        s_lo, s_hi = self.s_range()
        keys = jax.random.split(key, 1 + len(self.proposals))
        edges = uniform_edges(keys[0], n, self.counts[0], s_lo, s_hi, jitter=train)
        dir_norm = jnp.linalg.norm(d, axis=-1)
        rounds = []
        for field, p, k, n_next in zip(self.proposals, params["proposal"], keys[1:], self.counts[1:]):
            t = self.to_t(edges)
            mid = 0.5 * (t[:, 1:] + t[:, :-1])
            sigma = field.density(p, o[:, None, :] + mid[..., None] * d[:, None, :])
            w = compositing_weights(sigma, (t[:, 1:] - t[:, :-1]) * dir_norm[:, None])
            rounds.append((edges, w))
            edges = resample_edges(k, edges, jax.lax.stop_gradient(w) ** anneal, n_next, jitter=train)
        return edges, rounds

    def s_range(self) -> tuple[float, float]:
        """[s(near), s(far)]: the ray's range in the sampling coordinate."""
        r = self.field.radius
        return tuple(t / r if t <= r else 2.0 - r / t for t in (self.near, self.far))  # coord.spacing, on floats

    def to_t(self, s: jnp.ndarray) -> jnp.ndarray:
        """Ray distances t (z-depth units) of sampling coordinates s."""
        return spacing_inverse(s, self.field.radius)

    def render_rays(self, params, aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        """Render rays o, d [R, 3] (cones of radii [R] for the anti-aliased field): rgb [R, 3], depth, opacity,
        depth_normalized, depth_median [R]; with train, the field's edges and weights and the proposal rounds
        for the losses. complete [R] is all True (every ray fits)."""
        n = o.shape[0]
        k_sample, k_bg = jax.random.split(key)
        edges, rounds = self.sample(params, o, d, k_sample, train and self.cfg.sampler.perturb,
                                    self.anneal(aux["step"]) if train else 1.0)
        t = self.to_t(edges)
        t_mid = 0.5 * (t[:, 1:] + t[:, :-1])  # [R, N]
        dir_norm = jnp.linalg.norm(d, axis=-1)
        x = o[:, None, :] + t_mid[..., None] * d[:, None, :]
        viewdir = (d / dir_norm[:, None])[:, None, :]  # [R, 1, 3]: the field broadcasts per-ray inputs
        emb = self.field.embedding(params["field"], image_idx)
        if emb is not None:
            emb = emb[:, None, :]
        footprint = None
        if radii is not None:
            footprint = self.sample_scale(t_mid, dir_norm[:, None], radii[:, None])
        rgb, sigma = self.field(params["field"], x, viewdir, emb, footprint=footprint)
        w = compositing_weights(sigma, (t[:, 1:] - t[:, :-1]) * dir_norm[:, None])
        bg = jax.random.uniform(k_bg, (n, 3)) if (train and self.unbounded) else self.background
        out = composite(w, rgb, t_mid, bg)
        out["complete"] = jnp.ones(n, bool)
        out["n_samples"] = jnp.int32(n * self.counts[-1])
        if train:
            out["edges"], out["weights"], out["rounds"] = edges, w, rounds
        return out

    @staticmethod
    def losses(out: dict, target: jnp.ndarray, weights: jnp.ndarray | None = None):
        """MSE (weighted per ray when weights [R] are given) + the interlevel and distortion terms."""
        mse = weighted_mse(out["rgb"], target, weights)
        s_edges = [e for e, _ in out["rounds"]]
        prop = interlevel_loss(out["edges"], out["weights"], s_edges, [w for _, w in out["rounds"]])
        # The distortion loss in s / 2 (the sampling coordinate normalised to [0, 1]).
        dist = distortion_loss(0.5 * out["edges"], out["weights"])
        return mse + INTERLEVEL_MULT * prop + DISTORTION_MULT * dist, {"mse": mse, "interlevel": prop,
                                                                        "distortion": dist}

    def step_metrics(self, out: dict) -> dict:
        return {"rays": jnp.int32(out["rgb"].shape[0]), "samples_per_ray": jnp.float32(self.counts[-1])}
