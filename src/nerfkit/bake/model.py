"""A baked scene as a renderable model: the reference renderer of the baked format.

`BakedModel` has the fast field's marching interface (candidates, an occupancy grid, a
field returning (rgb, sigma)), so the wavefront renderer of inference.py renders it: the
occupancy grid is the brick index (a brick is occupied when it is stored), the field is the
trilinear look-up of format.py with the spherical-harmonics colour. What this renders is what
`nerfkit eval --baked` scores and what a browser renderer of the format must reproduce.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from nerfkit import occupancy
from nerfkit.bake.format import Baked, lookup
from nerfkit.encoding.sh import sh_encode


class BakedField:
    def __init__(self, baked: Baked):
        self.bound, self.resolution = baked.bound, baked.resolution
        self.bands = int(baked.meta["sh_bands"])
        self.unbounded = False
        self.radius = self.bound

    @staticmethod
    def to_grid(x):
        return x

    @staticmethod
    def embedding(params, image_idx):
        return None

    def density(self, params, x):
        return lookup(params, x.reshape(-1, 3), self.bound, self.resolution)[0].reshape(x.shape[:-1])

    def __call__(self, params, x, d, emb=None):
        """rgb [P, 3], sigma [P] at points x [P, 3] seen along unit directions d [P, 3]."""
        sigma, coeff = lookup(params, x, self.bound, self.resolution)
        y = sh_encode(d, self.bands)  # [P, SH]
        rgb = jnp.einsum("pck,pk->pc", coeff.reshape(x.shape[0], 3, -1), y)
        return jnp.clip(rgb, 0.0, 1.0), sigma


class BakedModel:
    """Marching like NGPModel (box candidates at t-step meta["step"]), the brick index as occupancy."""

    MIN_TRANSMITTANCE = 1e-4

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
        return {"field": baked.arrays()}, {"bits": jnp.asarray(baked.index.reshape(-1) >= 0)}

    def candidates(self, o, d, key=None, index=None):
        return occupancy.box_candidates(o, d, self.near, self.far, self.field.bound, self.step_size,
                                        self.march_steps, key, index)
