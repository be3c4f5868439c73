"""A baked scene as a renderable model: the reference renderer of the baked format.

`BakedModel` has the fast field's marching interface (candidates, an occupancy grid, a
field returning (rgb, sigma)), so the wavefront renderer of render/wavefront.py renders it: the
occupancy grid is the brick index (a brick is occupied when it is stored), the field is the
trilinear look-up of format.py with the spherical-harmonics colour. What this renders is what
`nerfkit eval --baked` scores and what a browser renderer of the format must reproduce.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.encoding.sh import sh_encode
from nerfkit.models.baked.format import Baked, lookup
from nerfkit.models.base import Supports
from nerfkit.render.volume import (
    packed_composite,
    packed_compositing_weights,
    segment_starts,
    segmented_cumsum,
)
from nerfkit.sampling import occupancy


class BakedField:
    def __init__(self, baked: Baked):
        self.bound, self.resolution = baked.bound, baked.resolution
        self.bands = int(baked.meta["sh_bands"])
        self.unbounded = False
        self.radius = self.bound
        self.lipschitz = 1.0  # grid coordinates are world coordinates (render/wavefront.py skips by it)

    @staticmethod
    def to_grid(x):
        return x

    @staticmethod
    def embedding(params, image_idx):
        return None

    def density(self, params, x, footprint=None):
        """sigma [...] at points x [..., 3] (one resolution: a footprint changes nothing)."""
        return lookup(params, x.reshape(-1, 3), self.bound, self.resolution)[0].reshape(x.shape[:-1])

    def __call__(self, params, x, d, emb=None, footprint=None):
        """rgb [P, 3], sigma [P] at points x [P, 3] seen along unit directions d [P, 3] (the baked grid has
        one resolution: a footprint does not change it)."""
        sigma, coeff = lookup(params, x, self.bound, self.resolution)
        y = sh_encode(d, self.bands)  # [P, SH]
        rgb = jnp.einsum("pck,pk->pc", coeff.reshape(x.shape[0], 3, -1), y)
        return jnp.clip(rgb, 0.0, 1.0), sigma


class BakedModel:
    """Marching like NGPModel (box candidates at t-step meta["step"]), the brick index as occupancy. It is
    rendered, never trained: it has what the wavefront renderer reads of a MarchingModel (field, occ,
    candidates, sample_scale, MIN_TRANSMITTANCE) and, for bake/finetune.py, render_packed."""

    MIN_TRANSMITTANCE = 1e-4
    supports = Supports(family="marching", mesh=False)

    def __init__(self, baked: Baked):
        m = baked.meta
        self.field = BakedField(baked)
        self.step_size = float(m["step"])
        self.march_steps = int(np.ceil(2 * np.sqrt(3) * baked.bound / self.step_size))
        self.near, self.far = float(m["near"]), float(m["far"])
        self.background = jnp.ones(3, jnp.float32) if m["background"] == "white" else jnp.zeros(3, jnp.float32)
        self.occ = occupancy.OccupancyConfig(resolution=baked.index.shape[0], bound=baked.bound)

    def params_and_aux(self, baked: Baked):
        """(params, aux) for the renderer: the look-up arrays, and the brick index as occupancy bits."""
        return {"field": baked.arrays()}, self.occupancy(baked.index)

    @staticmethod
    def occupancy(index: np.ndarray) -> dict:
        """The brick index [M, M, M] as the occupancy bits of the marcher (a brick is occupied when stored)."""
        return {"bits": jnp.asarray(index.reshape(-1) >= 0)}

    def candidates(self, o, d, key=None, index=None):
        return occupancy.box_candidates(o, d, self.near, self.far, self.field.bound, self.step_size,
                                        self.march_steps, key, index)

    @staticmethod
    def sample_scale(t, dir_norm, radii):
        """No footprints (see NGPModel.sample_scale): the baked grid is not anti-aliased."""
        return None

    def render_packed(self, params, aux, o, d, budget: int, live_budget: int | None = None) -> dict:
        """Differentiable render of rays o, d [R, 3] at the reference renderer's sample positions (used by
        finetune.py). The samples in stored bricks are packed into `budget` (occupancy.pack_candidates);
        with `live_budget`, a first pass of density alone finds the samples still seen, T_i >= 1e-4 (a
        prefix of each ray: T falls along it), and only those are looked up again, with colour and
        gradients, packed into `live_budget` (the others have weight 0 either way). Rays whose samples do
        not fit are marked incomplete (out["complete"] [R]) and must not be scored."""
        n = o.shape[0]
        t0, t1, cand = self.candidates(o, d)
        m = occupancy.pack_candidates(aux, o, d, t0, t1, cand, self.occ, budget)
        ray, complete = m["ray_idx"], m["complete"]
        valid = m["valid"] & complete[ray]
        norm = jnp.linalg.norm(d, axis=-1)
        t_mid = 0.5 * (m["t_start"] + m["t_end"])
        delta = (m["t_end"] - m["t_start"]) * norm[ray]
        if live_budget is not None:
            sigma = jax.lax.stop_gradient(self.field.density(params["field"], o[ray] + t_mid[:, None] * d[ray]))
            tau = jnp.where(valid, sigma * delta, 0.0)
            live = valid & (jnp.exp(-(segmented_cumsum(tau, segment_starts(ray)) - tau)) >= self.MIN_TRANSMITTANCE)
            complete = complete & (jnp.cumsum(jax.ops.segment_sum(live.astype(jnp.int32), ray, n)) <= live_budget)
            (sel,) = jnp.nonzero(live, size=live_budget, fill_value=0)
            kept = jnp.arange(live_budget) < jnp.sum(live)
            ray = jnp.where(kept, ray[sel], n - 1)
            t_mid, delta = t_mid[sel], jnp.where(kept, delta[sel], 0.0)
            valid = kept & complete[ray]
        rgb, sigma = self.field(params["field"], o[ray] + t_mid[:, None] * d[ray], d[ray] / norm[ray][:, None])
        w = packed_compositing_weights(sigma, delta, ray, valid, self.MIN_TRANSMITTANCE)
        out = packed_composite(w, rgb, t_mid, ray, n, self.background, self.far)
        out["complete"] = complete
        out["n_samples"] = jnp.sum(valid)
        return out
