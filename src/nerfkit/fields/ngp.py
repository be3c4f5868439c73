"""The fast field of Instant-NGP (Mueller et al. 2022): hash grid + two tiny MLPs.

    y      = x                     (bounded: the box [-B, B]^3)
             contract(x / R)       (unbounded: mip-NeRF 360's contraction, y in the ball of radius 2)
             ndc(x)                (unbounded, --warp ndc: a reference camera's NDC, y in [-1, 1]^3; R = n)
    h      = HashGrid((y + G) / 2G)                        (L*F features; G = B, 2 when contracted, 1 in NDC)
    z      = A_2 relu(A_1 h + b_1) + b_2                   (16 outputs, hidden width 64)
    sigma  = exp(min(z_0, 15))                             (truncated exponential)
    c      = sigmoid(MLP_64x64([z, SH_4(d), e_k]))         (degree-4 spherical harmonics)

With antialias (--antialias), each sample carries the std s of its pixel footprint (world units; the
field signature's `footprint`, models/base.py Field) and
level l's features are scaled by erf(h_l / (sqrt(8) s_y)) (encoding/hashgrid.level_weights; h_l the
level's cell size, s_y the footprint in grid coordinates: s, or s / R times the contraction's local
scale when contracted, or ndc_scale in NDC), so levels finer than the footprint fade out instead of aliasing.

e_k is the appearance embedding of training image k (NeRF-W; absent when
appearance_dim = 0); other views use the mean embedding. Same interface as the NeRF MLP:
`field(params, x, d, emb, footprint) -> (rgb, sigma)`, `field.density(params, x, footprint)`; the occupancy grid
uses `density_grid(params, y)`, the density at grid coordinates. Points outside a bounded
box get sigma = 0.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.core.config import FieldConfig
from nerfkit.encoding.hashgrid import HashGridConfig, encode_hashgrid, init_hashgrid
from nerfkit.encoding.sh import sh_encode
from nerfkit.fields.mlp import appearance_embedding, dense_init
from nerfkit.rays.coord import (
    CONTRACTED_BOUND,
    NDC_BOUND,
    contract,
    contraction_scale,
    ndc,
    ndc_scale,
    ndc_stretch,
    radial_stretch,
)

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
        self.unbounded = cfg.unbounded()
        self.ndc = None  # (frame [3, 4], near n, slopes (a_x, a_y)) in NDC
        if cfg.ndc():
            self.ndc = (jnp.asarray(cfg.ndc_frame, jnp.float32).reshape(3, 4), float(cfg.ndc_near),
                        tuple(map(float, cfg.ndc_extent)))
        # The radius R that scales sample spacing and initial densities: the near plane in NDC.
        self.radius = self.ndc[1] if self.ndc else cfg.resolved_bound()
        self.grid_bound = NDC_BOUND if self.ndc else CONTRACTED_BOUND if self.unbounded else self.radius
        self.n_appearance = cfg.n_appearance()

    def init(self, key) -> dict:
        k = jax.random.split(key, 6)
        h = self.cfg.hidden
        params = {
            "grid": init_hashgrid(k[0], self.grid),
            "density": [_layer(k[1], self.grid.output_dim, h), _layer(k[2], h, GEO_FEATURES)],
            "color": [_layer(k[3], GEO_FEATURES + SH_DEGREE**2 + self.n_appearance, h), _layer(k[4], h, h),
                      _layer(k[5], h, 3)],
        }
        if self.n_appearance:
            params["appearance"] = jnp.zeros((self.cfg.appearance_count, self.n_appearance), jnp.float32)
        return params

    def to_grid(self, x: jnp.ndarray) -> jnp.ndarray:
        """Grid coordinates y [..., 3] of world points x [..., 3]."""
        if self.ndc:
            return ndc(x, *self.ndc)
        return contract(x / self.radius) if self.unbounded else x

    def grid_scale(self, x: jnp.ndarray, footprint: jnp.ndarray) -> jnp.ndarray:
        """Footprint stds [...] in grid coordinates of footprints of std `footprint` [...] (world) at x [..., 3]."""
        if self.ndc:
            return footprint * ndc_scale(x, *self.ndc)
        if self.unbounded:
            return footprint / self.radius * contraction_scale(x / self.radius)
        return footprint

    @property
    def lipschitz(self) -> float:
        """A bound on how far grid points move per unit of world distance (render/empty_space.py skips by it):
        1 in a box, 1 / R contracted; in NDC, at depth z >= n, |J| <= sqrt(1/a_x^2 + 1/a_y^2 + y_1^2 + y_2^2
        + 4 n^2 / z^2) / z <= sqrt(1/a_x^2 + 1/a_y^2 + 12) / n with the coordinates clipped to [-2, 2]."""
        if self.ndc:
            (ax, ay), n = self.ndc[2], self.ndc[1]
            return float((1.0 / ax**2 + 1.0 / ay**2 + 12.0) ** 0.5 / n)
        return 1.0 / self.radius if self.unbounded else 1.0

    def stretch(self, y: jnp.ndarray) -> jnp.ndarray:
        """World length, in units of R, that a unit step of the grid covers at grid points y [..., 3] -> [...]
        (along the radius when contracted, along the depth axis in NDC; 1 in a box)."""
        if self.ndc:
            return ndc_stretch(y)
        return radial_stretch(y) if self.unbounded else jnp.ones(y.shape[:-1], y.dtype)

    def _geometry(self, params, y, scale_y=None):
        u = (y + self.grid_bound) / (2 * self.grid_bound)
        inside = jnp.all((u >= 0) & (u <= 1), axis=-1)
        flat = u.reshape(-1, 3)
        cube = None if scale_y is None else (scale_y / (2 * self.grid_bound)).reshape(-1)
        h = encode_hashgrid(params["grid"], flat, self.grid, cube)
        l1, l2 = params["density"]
        z = jax.nn.relu(h @ l1["w"] + l1["b"]) @ l2["w"] + l2["b"]
        z = z.reshape(*y.shape[:-1], GEO_FEATURES)
        sigma = jnp.where(inside, jnp.exp(jnp.minimum(z[..., 0], 15.0)), 0.0)
        return sigma, z

    def density_grid(self, params, y: jnp.ndarray) -> jnp.ndarray:
        """sigma [...] at grid coordinates y [..., 3] (world units of density)."""
        return self._geometry(params, y)[0]

    def density(self, params, x: jnp.ndarray, footprint: jnp.ndarray | None = None) -> jnp.ndarray:
        """sigma [...] >= 0 at world points x [..., 3] (footprints of std `footprint` [...] when anti-aliased)."""
        y = self.to_grid(x)
        return self._geometry(params, y, None if footprint is None else self.grid_scale(x, footprint))[0]

    def embedding(self, params, image_idx) -> jnp.ndarray | None:
        """Appearance embeddings [R, A] of training images image_idx [R] (None: the mean), or None without them."""
        return appearance_embedding(params, image_idx, self.n_appearance)

    def __call__(self, params, x: jnp.ndarray, d: jnp.ndarray, emb: jnp.ndarray | None = None,
                 footprint: jnp.ndarray | None = None):
        """rgb [..., 3], sigma [...] at x [..., 3] seen along unit directions d (broadcast to x),
        with appearance embeddings emb [..., A] (broadcast to x; needed when the field has them) and,
        anti-aliased, footprint stds [...] in world units (None: every level at full weight)."""
        sigma, z = self._geometry(params, self.to_grid(x),
                                  None if footprint is None else self.grid_scale(x, footprint))
        c1, c2, c3 = params["color"]
        # The first colour layer on [z, SH(d), e] as a sum of matmuls with its weights split by rows: the
        # direction and embedding terms are computed at their own shape (once per ray where they broadcast
        # over a ray's samples) and broadcast in the sum.
        w_z, w_sh, w_e = jnp.split(c1["w"], [GEO_FEATURES, GEO_FEATURES + SH_DEGREE**2])
        d = jnp.asarray(d, jnp.float32)
        per_ray = sh_encode(d.reshape(-1, 3), SH_DEGREE).reshape(*d.shape[:-1], -1) @ w_sh + c1["b"]
        if self.n_appearance:
            per_ray = per_ray + jnp.asarray(emb, jnp.float32) @ w_e
        h = jax.nn.relu(z @ w_z + per_ray)
        h = jax.nn.relu(h @ c2["w"] + c2["b"])
        return jax.nn.sigmoid(h @ c3["w"] + c3["b"]), sigma
