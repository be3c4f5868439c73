"""A toy rasteriser backend, as a user would add one (models/splat/backends.py): this module and one line in
BACKENDS. It is the reference rasteriser under another name, counting the times it is traced."""

from __future__ import annotations

from nerfkit.models.splat.backends import Backend
from nerfkit.models.splat.reference import rasterize_reference

TRACED = []  # the image sizes it was traced for (jax.jit traces a Python function once per shape)


def rasterize_toy(means2d, conics, colors, opacities, depths, radii, background, width, height):
    TRACED.append((int(width), int(height)))
    return rasterize_reference(means2d, conics, colors, opacities, depths, radii, background, width, height)


BACKEND = Backend(name="toy", summary="the reference, renamed", rasterize=rasterize_toy)
