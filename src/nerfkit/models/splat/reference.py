"""Brute-force Gaussian rasteriser in pure JAX: every pixel blends every Gaussian, by depth.

The definition both rasterisers implement. Gaussians are sorted front to back by depth (a
stable sort: equal depths keep their index order); culled ones (radius 0) are dropped. At
the pixel centre p = (j + 0.5, i + 0.5), Gaussian k with 2D mean m_k, conic (a, b, c),
opacity o_k and colour c_k [C] has

    d = m_k - p,   sigma_k = 0.5 (a d_x^2 + c d_y^2) + b d_x d_y
    alpha_k = min(ALPHA_MAX, o_k exp(-sigma_k)),

and is skipped (alpha_k := 0) when sigma_k < 0, when sigma_k > SIGMA_MAX (outside its
3-sigma ellipse, see below) or when alpha_k < ALPHA_MIN. Front to back, T_1 = 1 and

    T_{k+1} = T_k (1 - alpha_k),   colour = sum_k T_k alpha_k c_k + T_final background,

where blending stops before the first Gaussian that would bring T below T_MIN (that
Gaussian and all behind it are left out, as in the 3DGS code), so T_final >= T_MIN.

The 3-sigma ellipse cut (SIGMA_MAX = SIGMA_CUTOFF^2 / 2) makes the image independent of the
tile grid: a Gaussian's ellipse lies inside its radius square and so inside the tiles it is
binned to. (The 3DGS code instead cuts at the tile rectangle, which depends on the grid.)

This is O(pixels x Gaussians): used by the tests and where no host callback is wanted, with
autodiff for gradients. Pixels are processed in blocks (checkpointed for the backward pass) to
bound memory at a few block x N arrays.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.models.splat.backends import Backend
from nerfkit.models.splat.project import SIGMA_CUTOFF

ALPHA_MAX = 0.99
ALPHA_MIN = 1.0 / 255.0
T_MIN = 1e-4
SIGMA_MAX = 0.5 * SIGMA_CUTOFF**2
PAIRS_PER_BLOCK = 1 << 22  # pixel-Gaussian pairs per block (16 MiB per float32 [block, N] array)


def pixel_centres(width: int, height: int, dtype=jnp.float32) -> jax.Array:
    """(u, v) = (j + 0.5, i + 0.5) of all pixels, [H * W, 2] in row-major order."""
    v, u = jnp.meshgrid(jnp.arange(height, dtype=dtype) + 0.5, jnp.arange(width, dtype=dtype) + 0.5, indexing="ij")
    return jnp.stack([u.ravel(), v.ravel()], axis=-1)


def gaussian_alpha(pix, means2d, conics, opacities) -> jax.Array:
    """alpha [P, N] of Gaussians [N] at pixel centres pix [P, 2], with the skip rules applied (0)."""
    d = means2d[None, :, :] - pix[:, None, :]
    a, b, c = conics[:, 0], conics[:, 1], conics[:, 2]
    sigma = 0.5 * (a * d[..., 0] ** 2 + c * d[..., 1] ** 2) + b * d[..., 0] * d[..., 1]
    inside = (sigma >= 0.0) & (sigma <= SIGMA_MAX)
    alpha = jnp.minimum(ALPHA_MAX, opacities * jnp.exp(-jnp.where(inside, sigma, 0.0)))
    return jnp.where(inside & (alpha >= ALPHA_MIN), alpha, 0.0)


def blend(alpha, colors, background) -> tuple[jax.Array, jax.Array]:
    """Front-to-back blend of alpha [P, N] (depth order) and colours [N, C] on background [C].

    Returns colour [P, C] and T_final [P], with the T_MIN early stop (a prefix mask: the
    running product of (1 - alpha) is non-increasing, so once below T_MIN it stays there)."""
    keep = jnp.cumprod(1.0 - alpha, axis=-1) >= T_MIN  # T_{k+1} >= T_MIN, else stop at k
    alpha = jnp.where(keep, alpha, 0.0)
    one_minus = 1.0 - alpha
    trans = jnp.cumprod(jnp.concatenate([jnp.ones_like(alpha[:, :1]), one_minus[:, :-1]], axis=-1), axis=-1)
    color = (trans * alpha) @ colors
    t_final = trans[:, -1] * one_minus[:, -1] if alpha.shape[1] else jnp.ones(alpha.shape[0], alpha.dtype)
    return color + t_final[:, None] * background, t_final


def rasterize_reference(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
                        pixel_block: int | None = None) -> tuple[jax.Array, jax.Array]:
    """Render N projected Gaussians: means2d [N, 2], conics [N, 3], colors [N, C], opacities [N],
    depths [N], radii [N] (0 = culled), background [C]; width, height static.

    Returns image [H, W, C] and alpha [H, W] = 1 - T_final. Differentiable by autodiff in all
    float inputs except depths and radii (the order and culling are piecewise constant).
    pixel_block: pixels per step of the loop over the image (default: PAIRS_PER_BLOCK / N).
    """
    n = means2d.shape[0]
    if pixel_block is None:
        pixel_block = max(1, PAIRS_PER_BLOCK // max(n, 1))
    order = jnp.argsort(jax.lax.stop_gradient(depths), stable=True)
    live = (radii > 0)[order]
    m, q, col = means2d[order], conics[order], colors[order]
    op = jnp.where(live, opacities[order], 0.0)  # opacity 0 gives alpha 0 < ALPHA_MIN: skipped
    pix = pixel_centres(width, height, means2d.dtype)
    n_pix = width * height
    block = min(pixel_block, n_pix)
    n_blocks = -(-n_pix // block)
    pix = jnp.concatenate([pix, jnp.zeros((n_blocks * block - n_pix, 2), pix.dtype)]).reshape(n_blocks, block, 2)

    @jax.checkpoint  # under autodiff keep only each block's inputs, recompute its [block, N] arrays
    def render_block(p):
        if n == 0:
            return jnp.broadcast_to(background, (block, colors.shape[1])), jnp.ones(block, means2d.dtype)
        return blend(gaussian_alpha(p, m, q, op), col, background)

    color, t_final = jax.lax.map(render_block, pix)
    color = color.reshape(-1, colors.shape[1])[:n_pix].reshape(height, width, -1)
    return color, 1.0 - t_final.reshape(-1)[:n_pix].reshape(height, width)


BACKEND = Backend(name="reference", summary="pure JAX, every pixel blends every Gaussian (O(pixels x N)), autodiff",
                  rasterize=rasterize_reference)
