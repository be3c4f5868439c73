"""The differentiable rasteriser, through whichever backend is asked for (backends.py):

    image, alpha = rasterize(means2d, conics, colors, opacities, depths, radii, background, W, H, backend)
"""

from __future__ import annotations

import jax.numpy as jnp

from nerfkit.models.splat.backends import backend as backend_named


def rasterize(means2d, conics, colors, opacities, depths, radii, background, width: int, height: int,
              backend: str = "auto", return_contrib: bool = False):
    """Render N projected Gaussians (project.project_gaussians) into an image.

    Args:
      means2d [N, 2] pixel coordinates (u, v), conics [N, 3] (a, b, c) of the inverse 2D
      covariance (positive definite, as project_gaussians gives; the tile kernels skip
      others, the reference does not), colors [N, C], opacities [N] (in [0, 1]), depths [N] z-depth (sort key),
      radii [N] int (0 = culled), background [C]; width, height (static).
      backend: a name of backends.BACKENDS, or "auto" (backends.auto_name(): pallas on a GPU, numba elsewhere).
      return_contrib: also return n_contrib [H, W] int32 (backends with `contrib` only): 1 + the tile-list
      position of the last Gaussian each pixel blended (0: none).

    Returns image [H, W, C] and alpha [H, W] = 1 - T_final (and n_contrib if asked), in the
    dtype of `colors`.
    """
    b = backend_named(backend)
    colors = jnp.asarray(colors)
    args = (means2d, conics, colors, opacities, depths, radii, jnp.asarray(background, colors.dtype), width, height)
    if return_contrib:
        if b.contrib is None:
            raise ValueError(f"return_contrib needs a backend with tile lists; {b.name} has none")
        return b.contrib(*args)
    return b.rasterize(*args)
