"""The radiance field of the original NeRF: a positional-encoded MLP.

    h_0 = gamma(x)                                  (63 features for L_xyz = 10)
    h_l = relu(A_l h_{l-1} + b_l),  l = 1..D        (width W)
          with [gamma(x), h_{D/2+1}] fed to layer D/2+2 (the skip connection: for D=8
          the input is concatenated to the fifth layer's activation, as in the paper)
    sigma = relu(a_sigma . h_D + b_sigma)
    f     = A_f h_D + b_f                           (W features, no activation)
    c     = sigmoid(A_c relu(A_v [f, gamma(d), e_k] + b_v) + b_c)     (hidden width W/2)

mip-NeRF (kind "mip") feeds the integrated encoding of a Gaussian instead: h_0 = E[gamma(x)], x ~ N(mean,
diag(var)) (encoding/integrated.py), with the variances var passed as the sample's `footprint` next to the
mean (the field signature, models/base.py Field); everything else is the same MLP.

e_k is the appearance embedding of training image k (NeRF-W), present only when
appearance_dim > 0; views that are not training images use the mean embedding.

Params are a plain dict of arrays (Glorot-uniform weights, zero biases as in the original
TensorFlow code). Concatenations are written as sums of matmuls with split weights, so a
view direction shared by all samples of a ray ([R, 1, 3] against x [R, N, 3]) is encoded
and multiplied once per ray instead of once per sample.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.core.config import FieldConfig
from nerfkit.encoding.integrated import integrated_positional_encoding
from nerfkit.encoding.positional import encoded_size, positional_encoding


def appearance_embedding(params: dict, image_idx, n_appearance: int):
    """Rows image_idx [R] of params["appearance"] -> [R, A]; image_idx None: the mean row [1, A].
    None when the field has no embeddings."""
    if not n_appearance:
        return None
    table = params["appearance"]
    return jnp.mean(table, axis=0, keepdims=True) if image_idx is None else table[image_idx]


def dense_init(key, n_in: int, n_out: int) -> jnp.ndarray:
    """Glorot-uniform weights [n_in, n_out]."""
    limit = jnp.sqrt(6.0 / (n_in + n_out))
    return jax.random.uniform(key, (n_in, n_out), jnp.float32, -limit, limit)


class MLPField:
    """F(x, d) -> (rgb, sigma) of NeRF; `density(params, x)` evaluates sigma alone."""

    def __init__(self, cfg: FieldConfig, integrated: bool = False):
        """integrated: x arrives encoded by the integrated positional encoding (mip-NeRF), whatever cfg.pe."""
        self.cfg = cfg
        # 0-based index of the layer whose input gets gamma(x) again (5 for D=8, 3 for D=4).
        self.skip = cfg.depth // 2 + 1 if cfg.depth // 2 + 1 < cfg.depth else None
        self.x_dim = encoded_size(3, cfg.l_xyz, cfg.pe or integrated)
        self.d_dim = encoded_size(3, cfg.l_dir, cfg.pe)
        self.n_appearance = cfg.n_appearance() if cfg.viewdirs else 0

    def init(self, key) -> dict:
        c, w = self.cfg, self.cfg.width
        keys = iter(jax.random.split(key, c.depth + 8))
        trunk = []
        for layer in range(c.depth):
            n_in = self.x_dim if layer == 0 else w
            p = {"w": dense_init(next(keys), n_in, w), "b": jnp.zeros(w, jnp.float32)}
            if layer == self.skip:
                p["w_skip"] = dense_init(next(keys), self.x_dim, w)
            trunk.append(p)
        params = {"trunk": trunk, "sigma": {"w": dense_init(next(keys), w, 1), "b": jnp.zeros(1, jnp.float32)}}
        if c.viewdirs:
            half = max(w // 2, 1)
            params["feature"] = {"w": dense_init(next(keys), w, w), "b": jnp.zeros(w, jnp.float32)}
            params["view"] = {
                "w_f": dense_init(next(keys), w, half),
                "w_d": dense_init(next(keys), self.d_dim, half),
                "b": jnp.zeros(half, jnp.float32),
            }
            if self.n_appearance:
                params["view"]["w_a"] = dense_init(next(keys), self.n_appearance, half)
                params["appearance"] = jnp.zeros((c.appearance_count, self.n_appearance), jnp.float32)
            params["rgb"] = {"w": dense_init(next(keys), half, 3), "b": jnp.zeros(3, jnp.float32)}
        else:
            params["rgb"] = {"w": dense_init(next(keys), w, 3), "b": jnp.zeros(3, jnp.float32)}
        return params

    def _trunk(self, params, x, footprint=None):
        if footprint is None:
            ex = positional_encoding(x, self.cfg.l_xyz, self.cfg.pe)
        else:
            ex = integrated_positional_encoding(x, footprint, self.cfg.l_xyz)
        h = ex
        for layer, p in enumerate(params["trunk"]):
            z = h @ p["w"] + p["b"]
            if layer == self.skip:
                z = z + ex @ p["w_skip"]
            h = jax.nn.relu(z)
        return h

    def density(self, params, x: jnp.ndarray, footprint: jnp.ndarray | None = None) -> jnp.ndarray:
        """sigma [...] >= 0 at positions x [..., 3] (Gaussians of diagonal covariance footprint [..., 3], if given)."""
        h = self._trunk(params, x, footprint)
        return jax.nn.relu(h @ params["sigma"]["w"] + params["sigma"]["b"])[..., 0]

    def embedding(self, params, image_idx):
        return appearance_embedding(params, image_idx, self.n_appearance)

    def __call__(self, params, x: jnp.ndarray, d: jnp.ndarray, emb: jnp.ndarray | None = None,
                 footprint: jnp.ndarray | None = None):
        """rgb [..., 3] in (0, 1) and sigma [...] at x [..., 3] seen along unit directions d.

        d (and the appearance embeddings emb [..., A], when the field has them) broadcast
        against x (e.g. [R, 1, 3] for all samples of a ray). With footprint [..., 3], x and footprint are
        the mean and diagonal covariance of Gaussians, encoded with the integrated encoding (mip-NeRF).
        """
        h = self._trunk(params, x, footprint)
        sigma = jax.nn.relu(h @ params["sigma"]["w"] + params["sigma"]["b"])[..., 0]
        if self.cfg.viewdirs:
            f = h @ params["feature"]["w"] + params["feature"]["b"]
            ed = positional_encoding(d, self.cfg.l_dir, self.cfg.pe)
            v = params["view"]
            pre = ed @ v["w_d"] + v["b"]
            if self.n_appearance:
                pre = pre + emb @ v["w_a"]
            hv = jax.nn.relu(f @ v["w_f"] + pre)
            rgb = jax.nn.sigmoid(hv @ params["rgb"]["w"] + params["rgb"]["b"])
        else:
            rgb = jax.nn.sigmoid(h @ params["rgb"]["w"] + params["rgb"]["b"])
        return rgb, sigma
