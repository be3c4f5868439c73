"""Cones and conical frustums (mip-NeRF, Barron et al. 2021, sec. 3.1 and appendix A).

mip-NeRF casts a cone through each pixel instead of a ray: apex o, axis d (not normalised,
as everywhere in nerfkit: t is z-depth), and radius r(t) = t * base_radius at t, with
base_radius = 2 / sqrt(12) times the pixel's width in normalised image coordinates (the disc
whose variance matches the pixel's square footprint). A sample is the conical frustum
between t0 and t1, approximated by the Gaussian with the frustum's mean and covariance
(the points x = o + t d + t base_radius |d| u, u uniform in the unit disc orthogonal to d, t
distributed as t^2 on [t0, t1]: uniform in volume). With mu = (t0 + t1) / 2 and
w = (t1 - t0) / 2, in the numerically stable form of the paper (eq. 7):

    mean_t = mu + 2 mu w^2 / (3 mu^2 + w^2)
    var_t  = w^2 / 3 - (4 / 15) w^4 (12 mu^2 - w^2) / (3 mu^2 + w^2)^2
    var_r  = base_radius^2 |d|^2 (mu^2 / 4 + (5 / 12) w^2 - (4 / 15) w^4 / (3 mu^2 + w^2))

and in world coordinates (eq. 8, diagonal part, which is all the IPE needs):

    mean  = o + mean_t d
    Sigma = var_t d d^T + var_r (I - d d^T / |d|^2),   diag: var_t d^2 + var_r (1 - d^2 / |d|^2)
"""

from __future__ import annotations

import jax.numpy as jnp


def pixel_base_radius(fx, fy):
    """Cone radius per unit z-depth of a pixel of focal lengths fx, fy (pixels): the disc whose variance
    matches the pixel's square footprint, 2 / sqrt(12) * pixel width in normalised coordinates (the
    geometric mean of the two widths for non-square pixels)."""
    return 2.0 / jnp.sqrt(12.0) / jnp.sqrt(fx * fy)


def frustum_moments(t0, t1, base_radius, d_norm2):
    """(mean_t, var_t, var_r) [...] of conical frustums [t0, t1] [...] (module docstring)."""
    mu, w = 0.5 * (t0 + t1), 0.5 * (t1 - t0)
    den = 3.0 * mu**2 + w**2
    mean_t = mu + 2.0 * mu * w**2 / den
    var_t = w**2 / 3.0 - (4.0 / 15.0) * (w**4 * (12.0 * mu**2 - w**2)) / den**2
    var_r = base_radius**2 * d_norm2 * (mu**2 / 4.0 + (5.0 / 12.0) * w**2 - (4.0 / 15.0) * w**4 / den)
    return mean_t, var_t, var_r


def conical_frustum_to_gaussian(o, d, t0, t1, base_radius):
    """Mean [..., 3] and diagonal covariance [..., 3] of the frustums [t0, t1] [..., S] of cones with
    apex o [..., 3], axis d [..., 3] and radius t * base_radius * |d| ([...]): shapes [..., S, 3]."""
    d_norm2 = jnp.sum(d * d, axis=-1, keepdims=True)  # [..., 1]
    mean_t, var_t, var_r = frustum_moments(t0, t1, jnp.asarray(base_radius)[..., None], d_norm2)
    mean = o[..., None, :] + mean_t[..., None] * d[..., None, :]
    dd = (d * d)[..., None, :]
    var = var_t[..., None] * dd + var_r[..., None] * (1.0 - dd / d_norm2[..., None, :])
    return mean, var


def footprint_std(t, d_norm, base_radius):
    """Per-axis std [...] of a cone's cross-section at z-depth t [...] (|d| = d_norm, radius per unit z-depth
    base_radius): the disc of radius t |d| base_radius has variance (t |d| base_radius)^2 / 4 along each of
    its axes, i.e. the std of the pixel's square footprint (width w: w / sqrt(12)) at that distance."""
    return 0.5 * t * d_norm * base_radius
