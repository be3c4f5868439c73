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

Forward-facing captures (every camera facing one way, LLFF's) can use normalised device coordinates
instead (NeRF's NDC, Mildenhall et al. 2020 appendix C; TensoRF's for LLFF) of a reference camera
[R | c] (camera-to-world, looking along -z): with q = R^T (x - c) and depth z = -q_z,

    ndc(x) = (q_x / (a_x z), q_y / (a_y z), 1 - 2 n / z)

maps the frustum in front of the cameras, from the near plane z = n to infinity and out to the slopes
|q_x / z| <= a_x, |q_y / z| <= a_y, onto [-1, 1]^3: evenly in the image plane and evenly in disparity n / z
along the depth axis. Points nearer than n, behind the camera or outside the slopes land outside the cube.
The grid's cells then follow what the cameras resolve: ever coarser with depth, none spent behind the
cameras or beside their views, where the contraction spends seven eighths of its ball.
"""

from __future__ import annotations

import jax.numpy as jnp

CONTRACTED_BOUND = 2.0
NDC_BOUND = 1.0


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


def ndc(x: jnp.ndarray, frame: jnp.ndarray, near: float, extent: tuple[float, float]) -> jnp.ndarray:
    """ndc(x) [..., 3] of world points x [..., 3] (module docstring) for the reference camera frame [3, 4]
    = [R | c], near plane n and slopes extent = (a_x, a_y). Points at depth z <= 1e-6 n (at or behind the
    camera) and every coordinate are clipped to [-2, 2]: outside the cube, finite, with zero gradient."""
    frame = jnp.asarray(frame, jnp.float32)
    q = (x - frame[:, 3]) @ frame[:, :3]  # R^T (x - c), row vectors
    z = -q[..., 2]
    ahead = z > 1e-6 * near
    zs = jnp.where(ahead, z, near)
    y = jnp.stack([q[..., 0] / (extent[0] * zs), q[..., 1] / (extent[1] * zs), 1.0 - 2.0 * near / zs], -1)
    y = jnp.where(ahead[..., None], y, 2.0)
    return jnp.clip(y, -2.0, 2.0)


def ndc_inverse(y: jnp.ndarray, frame: jnp.ndarray, near: float, extent: tuple[float, float]) -> jnp.ndarray:
    """World points x [..., 3] of NDC points y [..., 3] with y_3 < 1: z = 2 n / (1 - y_3),
    q = (a_x y_1 z, a_y y_2 z, -z), x = R q + c."""
    frame = jnp.asarray(frame, jnp.float32)
    z = 2.0 * near / (1.0 - y[..., 2])
    q = jnp.stack([extent[0] * y[..., 0] * z, extent[1] * y[..., 1] * z, -z], -1)
    return q @ frame[:, :3].T + frame[:, 3]


def ndc_scale(x: jnp.ndarray, frame: jnp.ndarray, near: float, extent: tuple[float, float]) -> jnp.ndarray:
    """Isotropic local scale |det J|^(1/3) of ndc at world points x [..., 3] -> [...]: J is triangular in
    (q_x, q_y, z) with diagonal 1 / (a_x z), 1 / (a_y z), 2 n / z^2, so the scale is
    (2 n / (a_x a_y))^(1/3) z^(-4/3) (at depth z > 0; points behind get the near plane's)."""
    frame = jnp.asarray(frame, jnp.float32)
    z = -((x - frame[:, 3]) @ frame[:, 2])
    z = jnp.maximum(z, 1e-6 * near)
    return (2.0 * near / (extent[0] * extent[1])) ** (1.0 / 3.0) * z ** (-4.0 / 3.0)


def ndc_stretch(y: jnp.ndarray) -> jnp.ndarray:
    """dz / dy_3 in units of the near plane n at NDC points y [..., 3] -> [...]: z = 2 n / (1 - y_3), so
    2 / (1 - y_3)^2 (0.5 on the near plane, growing without bound towards infinity): as radial_stretch, the
    world length a step along the depth axis covers, per unit of the grid."""
    return 2.0 / jnp.maximum(1.0 - y[..., 2], 1e-3) ** 2
