"""Coordinates of unbounded scenes: mip-NeRF 360's contraction and the matching spacing of
samples along rays (Barron et al. 2022, Sec. 2 and eq. 10).

Scene points are first divided by the radius R of the inner ball (the `bound` of an
unbounded field), then contracted:

    contract(x) = x                          if |x| <= 1
                  (2 - 1/|x|) x / |x|        otherwise

which maps all of space into the ball of radius 2, linearly inside the unit ball and with
ever coarser resolution outside (distance 1/|x| shrinks, as disparity does). The
hash grid and the occupancy grid of an unbounded field live in [-2, 2]^3 of contracted
coordinates.

Samples along a ray follow the same curve in t (the spacing function of mip-NeRF 360 /
Zip-NeRF): s = g(t) = t / R for t <= R and 2 - R / t beyond, and candidates are spaced
evenly in s, hence evenly in t inside the inner ball and evenly in disparity 1/t outside.
"""

from __future__ import annotations

import jax.numpy as jnp

CONTRACTED_BOUND = 2.0


def contract(x: jnp.ndarray) -> jnp.ndarray:
    """contract(x) [..., 3] of points x [..., 3] (see module docstring)."""
    n2 = jnp.maximum(jnp.sum(x * x, axis=-1, keepdims=True), 1e-12)
    n = jnp.sqrt(n2)
    return jnp.where(n <= 1.0, x, (2.0 - 1.0 / n) * x / n)



def radial_stretch(y: jnp.ndarray) -> jnp.ndarray:
    """d|x| / d|y| at contracted points y [..., 3] -> [...]: 1 inside the unit ball,
    1 / (2 - |y|)^2 outside. A step of length h along a ray in contracted space near y
    covers about h * radial_stretch(y) in (R-scaled) world units."""
    n = jnp.linalg.norm(y, axis=-1)
    return jnp.where(n <= 1.0, 1.0, 1.0 / jnp.maximum(2.0 - n, 1e-3) ** 2)


def contraction_scale(x: jnp.ndarray) -> jnp.ndarray:
    """Isotropic local scale |det J|^(1/3) of contract at points x [..., 3] -> [...]: 1 inside the unit
    ball; outside, J has the radial eigenvalue 1 / |x|^2 and two tangential ones (2 - 1/|x|) / |x|, so
    the scale is ((2 - 1/|x|)^2 / |x|^4)^(1/3). A small ball of radius r around x maps to about radius
    r * contraction_scale(x)."""
    n = jnp.maximum(jnp.linalg.norm(x, axis=-1), 1e-12)
    out = jnp.cbrt((2.0 - 1.0 / n) ** 2 / n**4)
    return jnp.where(n <= 1.0, 1.0, out)


def spacing(t: jnp.ndarray, radius: float) -> jnp.ndarray:
    """s = g(t): t / R for t <= R, 2 - R / t beyond (continuous, with slope 1/R at t = R)."""
    u = t / radius
    return jnp.where(u <= 1.0, u, 2.0 - 1.0 / jnp.maximum(u, 1e-12))


def spacing_inverse(s: jnp.ndarray, radius: float) -> jnp.ndarray:
    """t = g^-1(s): R s for s <= 1, R / (2 - s) beyond (s < 2)."""
    return jnp.where(s <= 1.0, radius * s, radius / jnp.maximum(2.0 - s, 1e-12))
