"""The fast field of Instant-NGP (Mueller et al. 2022): hash grid + two tiny MLPs.

    h      = HashGrid((x + B) / 2B)                        (L*F features, x in [-B, B]^3)
    z      = A_2 relu(A_1 h + b_1) + b_2                   (16 outputs, hidden width 64)
    sigma  = exp(min(z_0, 15))                             (truncated exponential)
    c      = sigmoid(MLP_64x64([z, SH_4(d)]))              (degree-4 spherical harmonics)

Same interface as the NeRF MLP: `field(params, x, d) -> (rgb, sigma)`,
`field.density(params, x)`. Points outside the box get sigma = 0.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.config import FieldConfig
from nerfkit.encoding.hashgrid import HashGridConfig, encode_hashgrid, init_hashgrid
from nerfkit.encoding.sh import sh_encode
from nerfkit.fields.mlp import dense_init

GEO_FEATURES = 16  # outputs of the density MLP: log-density + 15 geometry features
SH_DEGREE = 4


def hashgrid_config(cfg: FieldConfig) -> HashGridConfig:
    return HashGridConfig(n_levels=cfg.hash_levels, features_per_level=cfg.hash_features,
                          log2_table_size=cfg.hash_log2_size, base_resolution=cfg.hash_base_res,
                          finest_resolution=cfg.hash_max_res)


def _layer(key, n_in, n_out):
    return {"w": dense_init(key, n_in, n_out), "b": jnp.zeros(n_out, jnp.float32)}


class HashGridField:
    def __init__(self, cfg: FieldConfig):
        self.cfg = cfg
        self.grid = hashgrid_config(cfg)
        self.bound = cfg.bound

    def init(self, key) -> dict:
        k = jax.random.split(key, 6)
        h = self.cfg.hidden
        return {
            "grid": init_hashgrid(k[0], self.grid),
            "density": [_layer(k[1], self.grid.output_dim, h), _layer(k[2], h, GEO_FEATURES)],
            "color": [_layer(k[3], GEO_FEATURES + SH_DEGREE**2, h), _layer(k[4], h, h), _layer(k[5], h, 3)],
        }

    def _geometry(self, params, x):
        u = (x + self.bound) / (2 * self.bound)
        inside = jnp.all((u >= 0) & (u <= 1), axis=-1)
        flat = u.reshape(-1, 3)
        h = encode_hashgrid(params["grid"], flat, self.grid)
        l1, l2 = params["density"]
        z = jax.nn.relu(h @ l1["w"] + l1["b"]) @ l2["w"] + l2["b"]
        z = z.reshape(*x.shape[:-1], GEO_FEATURES)
        sigma = jnp.where(inside, jnp.exp(jnp.minimum(z[..., 0], 15.0)), 0.0)
        return sigma, z

    def density(self, params, x: jnp.ndarray) -> jnp.ndarray:
        """sigma [...] >= 0 at x [..., 3]."""
        return self._geometry(params, x)[0]

    def __call__(self, params, x: jnp.ndarray, d: jnp.ndarray):
        """rgb [..., 3], sigma [...] at x [..., 3] seen along unit directions d (broadcast to x)."""
        sigma, z = self._geometry(params, x)
        sh = sh_encode(jnp.broadcast_to(d, x.shape).reshape(-1, 3), SH_DEGREE).reshape(*x.shape[:-1], -1)
        h = jnp.concatenate([z, sh], axis=-1)
        c1, c2, c3 = params["color"]
        h = jax.nn.relu(h @ c1["w"] + c1["b"])
        h = jax.nn.relu(h @ c2["w"] + c2["b"])
        return jax.nn.sigmoid(h @ c3["w"] + c3["b"]), sigma
