"""The colour of surface points as the rendered views show it: for runs without a density field to look
into (Gaussian splats), the mesh's vertex colours and texture come from the model's own renders.

View k (pinhole, c2w_k, intrinsics, rendered rgb_k, opacity A_k and median depth D_k [H, W], tsdf.pixel_of)
sees a surface point x with outward normal n at pixel (u, v) and z-depth z when

    A_k(u, v) >= 1/2,   |D_k(u, v) - z| <= tol + z / f_k   (the first surface there)   and   cos_k > 0,

cos_k = n . (o_k - x) / |o_k - x|. Its colour there, un-composited from the background b,
c_k = (rgb_k - (1 - A_k) b) / A_k (bilinear in rgb and A), enters a mean weighted by cos_k^2 (head-on
views count most; highlights that move from view to view average out):

    c(x) = sum_k [seen_k] cos_k^2 c_k / sum_k [seen_k] cos_k^2.

A point no view sees (inside a closed --watertight surface, under an object) takes the same mean over
the views it faces regardless of depth, and grey where it faces none.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.export.tsdf import A_FREE, pixel_of

UNSEEN_GREY = 0.5


def _bilinear(img, u, v):
    """img [H, W, C] at pixel coordinates (u, v) [M] (pixel centres at +0.5, edges clamped): [M, C]."""
    h, w = img.shape[:2]
    x = jnp.clip(u - 0.5, 0.0, w - 1.0)
    y = jnp.clip(v - 0.5, 0.0, h - 1.0)
    x0 = jnp.clip(jnp.floor(x).astype(jnp.int32), 0, w - 2)
    y0 = jnp.clip(jnp.floor(y).astype(jnp.int32), 0, h - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x0 + 1] * fx
    bottom = img[y0 + 1, x0] * (1 - fx) + img[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bottom * fy


def view_color_fn(c2w: np.ndarray, intrinsics: np.ndarray, rgb: np.ndarray, opacity: np.ndarray, depth: np.ndarray,
                  background, tol: float):
    """A jitted (x [M, 3], n [M, 3]) -> rgb [M, 3] in [0, 1]: c(x) of the module docstring over the views
    c2w [V, 4, 4], intrinsics [V, 4], rgb [V, H, W, 3], opacity and median depth [V, H, W]; tol in units of
    length (a pixel's footprint z / f is added)."""
    views = tuple(jnp.asarray(a, jnp.float32) for a in (c2w, intrinsics, rgb, opacity, depth))
    bg = jnp.asarray(background, jnp.float32)
    h, w = opacity.shape[1:]

    @jax.jit
    def colors(x, n):
        def body(acc, view):
            c2w_k, k, rgb_k, a_k, d_k = view
            u, v, z, inside, iv, iu = pixel_of(x, c2w_k, k, h, w)
            to_cam = c2w_k[:3, 3] - x
            cos = jnp.sum(n * to_cam, -1) / jnp.maximum(jnp.linalg.norm(to_cam, axis=-1), 1e-9)
            first = (a_k[iv, iu] >= A_FREE) & (jnp.abs(d_k[iv, iu] - z) <= tol + z / k[0])
            sample = _bilinear(jnp.concatenate([rgb_k, a_k[..., None]], -1), u, v)
            a = jnp.maximum(sample[:, 3:], 1e-3)
            col = jnp.clip((sample[:, :3] - (1.0 - a) * bg) / a, 0.0, 1.0)
            facing = jnp.where(inside & (cos > 0), cos * cos, 0.0)
            seen = jnp.where(first, facing, 0.0)
            return (acc[0] + seen[:, None] * col, acc[1] + seen, acc[2] + facing[:, None] * col, acc[3] + facing), None

        m = x.shape[0]
        zero3, zero = jnp.zeros((m, 3), jnp.float32), jnp.zeros(m, jnp.float32)
        (cs, ws, cf, wf), _ = jax.lax.scan(body, (zero3, zero, zero3, zero), views)
        seen = cs / jnp.maximum(ws, 1e-12)[:, None]
        faced = jnp.where(wf[:, None] > 0, cf / jnp.maximum(wf, 1e-12)[:, None], UNSEEN_GREY)
        return jnp.where(ws[:, None] > 0, seen, faced)

    return colors
