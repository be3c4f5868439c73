"""The differentiable tile rasteriser as a JAX function (CPU kernels through jax.pure_callback).

    image, alpha = rasterize(means2d, conics, colors, opacities, depths, radii, background, W, H)

renders the image defined in reference.py (front-to-back alpha blending of depth-sorted
Gaussians with the 3DGS skip and early-stop rules) with the numba tile kernels of
tiles_numba.py. It works inside jax.jit, jax.grad and jax.vmap (sequentially): the forward
runs on the host and returns the image, T_final = 1 - alpha and the per-pixel contributor
count; the custom VJP hands them back to the host backward kernel, which rebuilds the
tile lists (cheap next to the blend) and returns the gradients

    dL/d means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], background [C].

depths and radii get none (the depth order and the culling are piecewise constant). The
colour channels are free: pass [N, 3] colours, or e.g. [N, 4] colour + depth for a depth map
(channel 4 then renders sum_k w_k z_k, and its gradient flows into the depths through it).

`rasterize_reference` is the same function in pure JAX (no tiles, O(pixels x N)): the tests'
definition, or where no host callback is wanted. `backend="auto"` picks the host kernels on every
platform: on a GPU the rest of a step stays on the device and only the rasteriser's inputs and
outputs (a few MB) cross to the host. The reference on a GPU was measured too slow to train with
(an H200, lego at 200x200, 50k Gaussians: 1.1 steps/s against about 10 on 2 CPU cores; an 800x800
frame did not finish in two minutes; benchmarks/results/gpu_h200/).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import tiles_numba
from nerfkit.models.splat.reference import rasterize_reference


def _host(x) -> np.ndarray:
    """A C-contiguous writable numpy copy-if-needed of a callback argument (one compiled kernel variant)."""
    return np.require(np.asarray(x), requirements=["C", "W"])


def _forward_host(means2d, conics, colors, opacities, depths, radii, background, *, width, height):
    args = [_host(a) for a in (means2d, conics, colors, opacities, depths, radii, background)]
    return tiles_numba.forward(*args, width, height)


def _backward_host(means2d, conics, colors, opacities, depths, radii, background, t_final, n_contrib, g_img, g_t, *,
                   width, height):
    args = [_host(a) for a in (means2d, conics, colors, opacities, depths, radii, background)]
    return tiles_numba.backward(*args, width, height, *(_host(a) for a in (t_final, n_contrib, g_img, g_t)))


def _forward_call(inputs, width, height):
    colors = inputs[2]
    shapes = (jax.ShapeDtypeStruct((height, width, colors.shape[1]), colors.dtype),
              jax.ShapeDtypeStruct((height, width), colors.dtype),
              jax.ShapeDtypeStruct((height, width), jnp.int32))
    return jax.pure_callback(partial(_forward_host, width=width, height=height), shapes, *inputs,
                             vmap_method="sequential")


@partial(jax.custom_vjp, nondiff_argnums=(7, 8))
def _rasterize(means2d, conics, colors, opacities, depths, radii, background, width, height):
    image, t_final, n_contrib = _forward_call((means2d, conics, colors, opacities, depths, radii, background),
                                              width, height)
    return image, t_final, n_contrib


def _rasterize_fwd(means2d, conics, colors, opacities, depths, radii, background, width, height):
    inputs = (means2d, conics, colors, opacities, depths, radii, background)
    image, t_final, n_contrib = _forward_call(inputs, width, height)
    return (image, t_final, n_contrib), (inputs, t_final, n_contrib)


def _rasterize_bwd(width, height, res, cotangents):
    inputs, t_final, n_contrib = res
    g_img, g_t, _ = cotangents
    shapes = tuple(jax.ShapeDtypeStruct(inputs[i].shape, inputs[i].dtype) for i in (0, 1, 2, 3, 6))
    g_m, g_q, g_c, g_o, g_bg = jax.pure_callback(
        partial(_backward_host, width=width, height=height), shapes, *inputs, t_final, n_contrib,
        g_img.astype(inputs[2].dtype), g_t.astype(inputs[2].dtype), vmap_method="sequential")
    return g_m, g_q, g_c, g_o, None, None, g_bg


_rasterize.defvjp(_rasterize_fwd, _rasterize_bwd)


def rasterize(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
              backend: str = "auto", return_contrib: bool = False):
    """Render N projected Gaussians (project.project_gaussians) into an image.

    Args:
      means2d [N, 2] pixel coordinates (u, v), conics [N, 3] (a, b, c) of the inverse 2D
      covariance (positive definite, as project_gaussians gives; the tile kernels skip
      others, the reference does not), colors [N, C], opacities [N] (in [0, 1]), depths [N] z-depth (sort key),
      radii [N] int (0 = culled), background [C]; width, height (static).
      backend: "numba" (CPU tile kernels), "reference" (pure JAX brute force) or "auto"
      (numba, whatever the default device: see the module docstring).
      return_contrib: also return n_contrib [H, W] int32 (numba only): 1 + the tile-list
      position of the last Gaussian each pixel blended (0: none).

    Returns image [H, W, C] and alpha [H, W] = 1 - T_final (and n_contrib if asked), in the
    dtype of `colors`.
    """
    if backend == "auto":
        backend = "numba"
    colors = jnp.asarray(colors)
    background = jnp.asarray(background, colors.dtype)
    if backend == "reference":
        if return_contrib:
            raise ValueError("return_contrib needs the numba backend")
        return rasterize_reference(means2d, conics, colors, opacities, depths, radii, background, width, height)
    if backend != "numba":
        raise ValueError(f"unknown rasteriser backend {backend!r}")
    dtype = colors.dtype
    image, t_final, n_contrib = _rasterize(jnp.asarray(means2d, dtype), jnp.asarray(conics, dtype), colors,
                                           jnp.asarray(opacities, dtype), jnp.asarray(depths, dtype),
                                           jnp.asarray(radii, jnp.int32), background, int(width), int(height))
    if return_contrib:
        return image, 1.0 - t_final, n_contrib
    return image, 1.0 - t_final
