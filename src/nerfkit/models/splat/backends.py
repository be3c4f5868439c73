"""Rasteriser backends, by name (--backend): adding one is a module defining BACKEND (a `Backend`) and one
line in BACKENDS; `--backend auto` picks AUTO[platform] for JAX's default device ("gpu", "cpu", ...).

The interface. With N projected Gaussians (project.project_gaussians) and static width W, height H:

    rasterize(means2d [N, 2], conics [N, 3], colors [N, C], opacities [N], depths [N], radii [N] int,
              background [C], W, H) -> (image [H, W, C], alpha [H, W] = 1 - T_final)

is the image reference.py defines (depth-sorted front-to-back blending with the 3DGS skip and
early-stop rules), in the dtype of `colors`. It must work inside jax.jit and jax.grad, with
gradients for means2d, conics, colors, opacities and background (by autodiff, or a jax.custom_vjp
around a forward and a backward kernel); depths and radii get none (the order and the culling are
piecewise constant).

    contrib(...same arguments) -> (image, alpha, n_contrib [H, W] int32)   optional

also returns each pixel's contributor count (1 + the tile-list position of the last Gaussian it
blended, 0: none), for backends that bin Gaussians into tiles.

    frame(...same arguments, numpy) -> (rgb [H, W, 3] clipped to [0, 1], extra [H, W, C - 3], alpha [H, W])
                                                                        optional

renders a view that is only looked at, outside jit and with no gradient to follow, for backends that
render on the host (gaussians.render_frame calls it, and the jitted rasterize where it is None).

A kernel backend is built in three parts (tiles_numba.py is the model): bin (the Gaussians each
tile may see, in depth order), forward (image, T_final and n_contrib per pixel) and backward (from
T_final and n_contrib, the gradients above), joined by a custom VJP (rasterize_numba.py).

tests/models/splat/test_rasterize.py holds every backend to the reference, image and gradients.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

import jax

from nerfkit.core.errors import ConfigError

BACKENDS: dict[str, str] = {  # name -> the module that defines its BACKEND (imported when used)
    "numba": "nerfkit.models.splat.rasterize_numba",
    "pallas": "nerfkit.models.splat.rasterize_pallas",
    "reference": "nerfkit.models.splat.reference",
}
AUTO = {"gpu": "pallas"}  # JAX's default platform -> its backend; any other platform: AUTO_OTHER
AUTO_OTHER = "numba"  # host kernels; on a CPU the pallas kernels run interpreted (tests only)


@dataclass(frozen=True)
class Backend:
    name: str
    summary: str
    rasterize: Callable
    contrib: Callable | None = None
    frame: Callable | None = None


def backend(name: str) -> Backend:
    """The backend called `name` ("auto": auto_name()); ConfigError naming the ones there are otherwise."""
    name = auto_name() if name == "auto" else name
    if name not in BACKENDS:
        raise ConfigError(f"--backend must be auto or one of {', '.join(BACKENDS)} (got {name!r})")
    return importlib.import_module(BACKENDS[name]).BACKEND


def auto_name() -> str:
    """The backend "auto" means on JAX's default device: AUTO[platform], else AUTO_OTHER."""
    return AUTO.get(jax.default_backend(), AUTO_OTHER)
