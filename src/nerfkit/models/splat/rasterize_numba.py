"""The "numba" rasteriser backend (backends.py): the CPU tile kernels of tiles_numba.py as a differentiable
JAX function, through jax.pure_callback.

    image, t_final, n_contrib = rasterize_numba(means2d, conics, colors, opacities, depths, radii, background, W, H)

renders the image defined in reference.py (front-to-back alpha blending of depth-sorted
Gaussians with the 3DGS skip and early-stop rules). It works inside jax.jit, jax.grad and jax.vmap
(sequentially): the forward runs on the host and returns the image, T_final = 1 - alpha and the
per-pixel contributor count; the custom VJP hands them back to the host backward kernel, which
takes the forward's tile lists (kept on the host under a token that the forward returns as a residual;
binned again if they are gone, tiles_numba.KEPT_BINS) and returns the gradients

    dL/d means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], background [C].

depths and radii get none (the depth order and the culling are piecewise constant). It is the
"auto" choice off a GPU. On a GPU it runs too (the rest of a step stays on the device and only the
rasteriser's inputs and outputs, a few MB, cross to the host) but "auto" picks the pallas kernels there.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import tiles_numba
from nerfkit.models.splat.backends import Backend


def _host(x) -> np.ndarray:
    """A C-contiguous writable numpy copy-if-needed of a callback argument (one compiled kernel variant)."""
    return np.require(np.asarray(x), requirements=["C", "W"])


def _forward_host(means2d, conics, colors, opacities, depths, radii, background, *, width, height, keep):
    args = [_host(a) for a in (means2d, conics, colors, opacities, depths, radii, background)]
    if not keep:
        return tiles_numba.forward(*args, width, height)
    image, t_final, n_contrib, token = tiles_numba.forward(*args, width, height, keep_bins=True)
    return image, t_final, n_contrib, np.asarray(token, np.int32)


def _backward_host(means2d, conics, colors, opacities, depths, radii, background, t_final, n_contrib, g_img, g_t,
                   token, *, width, height):
    args = [_host(a) for a in (means2d, conics, colors, opacities, depths, radii, background)]
    return tiles_numba.backward(*args, width, height, *(_host(a) for a in (t_final, n_contrib, g_img, g_t)),
                                bins=int(token))


def _forward_call(inputs, width, height, keep=False):
    """The host forward: (image, t_final, n_contrib), and with keep a token (int32 []) under which its tile
    lists wait for the backward (tiles_numba.KEPT_BINS)."""
    colors = inputs[2]
    shapes = (jax.ShapeDtypeStruct((height, width, colors.shape[1]), colors.dtype),
              jax.ShapeDtypeStruct((height, width), colors.dtype),
              jax.ShapeDtypeStruct((height, width), jnp.int32))
    if keep:
        shapes += (jax.ShapeDtypeStruct((), jnp.int32),)
    return jax.pure_callback(partial(_forward_host, width=width, height=height, keep=keep), shapes, *inputs,
                             vmap_method="sequential")


@partial(jax.custom_vjp, nondiff_argnums=(7, 8))
def _rasterize(means2d, conics, colors, opacities, depths, radii, background, width, height):
    image, t_final, n_contrib = _forward_call((means2d, conics, colors, opacities, depths, radii, background),
                                              width, height)
    return image, t_final, n_contrib


def _rasterize_fwd(means2d, conics, colors, opacities, depths, radii, background, width, height):
    inputs = (means2d, conics, colors, opacities, depths, radii, background)
    image, t_final, n_contrib, token = _forward_call(inputs, width, height, keep=True)
    return (image, t_final, n_contrib), (inputs, t_final, n_contrib, token)


def _rasterize_bwd(width, height, res, cotangents):
    inputs, t_final, n_contrib, token = res
    g_img, g_t, _ = cotangents
    shapes = tuple(jax.ShapeDtypeStruct(inputs[i].shape, inputs[i].dtype) for i in (0, 1, 2, 3, 6))
    g_m, g_q, g_c, g_o, g_bg = jax.pure_callback(
        partial(_backward_host, width=width, height=height), shapes, *inputs, t_final, n_contrib,
        g_img.astype(inputs[2].dtype), g_t.astype(inputs[2].dtype), token, vmap_method="sequential")
    return g_m, g_q, g_c, g_o, None, None, g_bg


_rasterize.defvjp(_rasterize_fwd, _rasterize_bwd)


def rasterize_numba(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int):
    """(image [H, W, C], alpha [H, W], n_contrib [H, W] int32) in the dtype of `colors`: n_contrib is 1 + the
    tile-list position of the last Gaussian each pixel blended (0: none)."""
    dtype = colors.dtype
    image, t_final, n_contrib = _rasterize(jnp.asarray(means2d, dtype), jnp.asarray(conics, dtype), colors,
                                           jnp.asarray(opacities, dtype), jnp.asarray(depths, dtype),
                                           jnp.asarray(radii, jnp.int32), background, int(width), int(height))
    return image, 1.0 - t_final, n_contrib


BACKEND = Backend(
    name="numba", summary="CPU tile kernels (numba) through a host callback, custom VJP",
    rasterize=lambda *a: rasterize_numba(*a)[:2], contrib=rasterize_numba, frame=tiles_numba.frame)
