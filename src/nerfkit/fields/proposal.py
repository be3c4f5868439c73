"""The proposal density field of proposal sampling (sampling/proposal.py; nerfacto's proposal networks):
a small hash grid and a one-layer MLP that say where a ray's weight lies, at a fraction of the radiance
field's cost per sample.

    y      = contract(x / R)                       (the radiance field's grid coordinates, fields/ngp.py)
    h      = HashGrid((y + G) / 2G)                (L levels x 2 features, coarse: finest N_max cells)
    sigma  = exp(min(A_2 relu(A_1 h + b_1) + b_2, 15))

No colour, no view direction, no appearance: only sigma [...] at points x [..., 3]."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from nerfkit.encoding.hashgrid import HashGridConfig, encode_hashgrid, init_hashgrid
from nerfkit.fields.mlp import dense_init


@dataclass(frozen=True)
class ProposalFieldConfig:
    """levels L, finest resolution N_max (coarsest 16), log2 table size and MLP width (nerfacto: 5 levels,
    128 then 256, 2^17 rows, 16 wide)."""

    levels: int = 5
    max_res: int = 128
    log2_size: int = 17
    hidden: int = 16


class ProposalField:
    """sigma(x) of one proposal round; `to_grid` maps world points to the grid coordinates in [-G, G]^3."""

    def __init__(self, cfg: ProposalFieldConfig, to_grid: Callable, grid_bound: float):
        self.cfg = cfg
        self.grid = HashGridConfig(n_levels=cfg.levels, features_per_level=2, log2_table_size=cfg.log2_size,
                                   base_resolution=16, finest_resolution=cfg.max_res)
        self.to_grid = to_grid
        self.grid_bound = grid_bound

    def init(self, key) -> dict:
        k = jax.random.split(key, 3)
        h = self.cfg.hidden
        return {"grid": init_hashgrid(k[0], self.grid),
                "w1": dense_init(k[1], self.grid.output_dim, h), "b1": jnp.zeros(h, jnp.float32),
                "w2": dense_init(k[2], h, 1), "b2": jnp.zeros(1, jnp.float32)}

    def density(self, params: dict, x: jnp.ndarray) -> jnp.ndarray:
        """sigma [...] >= 0 at world points x [..., 3]."""
        y = self.to_grid(x)
        u = ((y + self.grid_bound) / (2 * self.grid_bound)).reshape(-1, 3)
        h = encode_hashgrid(params["grid"], u, self.grid)
        z = jax.nn.relu(h @ params["w1"] + params["b1"]) @ params["w2"] + params["b2"]
        return jnp.exp(jnp.minimum(z[:, 0], 15.0)).reshape(x.shape[:-1])
