"""Conical frustums as Gaussians (mip-NeRF): moments against points sampled in the frustum."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.rays.frustum import conical_frustum_to_gaussian, pixel_base_radius


def sample_frustum(rng, o, d, t0, t1, base_radius, n):
    """Points uniform in the volume of the frustum [t0, t1] of the cone (o, d, radius t base_radius |d|)."""
    t = (t0**3 + rng.uniform(size=n) * (t1**3 - t0**3)) ** (1 / 3)  # density ~ t^2
    r = t * base_radius * np.linalg.norm(d) * np.sqrt(rng.uniform(size=n))  # uniform in the disc
    phi = rng.uniform(0, 2 * np.pi, n)
    a = np.cross(d, [1.0, 0, 0] if abs(d[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(d / np.linalg.norm(d), a)
    return o + t[:, None] * d + r[:, None] * (np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b)


@pytest.mark.parametrize("t0, t1, base_radius", [(2.0, 2.5, 0.05), (0.5, 3.0, 0.2), (4.0, 4.01, 0.01)])
def test_frustum_gaussian_matches_sampled_points(t0, t1, base_radius):
    rng = np.random.default_rng(0)
    o, d = np.array([0.1, -0.2, 0.3]), np.array([0.3, 0.8, -1.0])
    pts = sample_frustum(rng, o, d, t0, t1, base_radius, 400_000)
    mean, var = conical_frustum_to_gaussian(jnp.asarray(o[None], jnp.float32), jnp.asarray(d[None], jnp.float32),
                                            jnp.asarray([[t0]], jnp.float32), jnp.asarray([[t1]], jnp.float32),
                                            jnp.asarray([base_radius], jnp.float32))
    mean, var = np.asarray(mean)[0, 0], np.asarray(var)[0, 0]
    se = np.sqrt(pts.var(0) / len(pts))
    assert np.all(np.abs(mean - pts.mean(0)) < 5 * se + 1e-5)
    np.testing.assert_allclose(var, pts.var(0), rtol=0.02, atol=1e-8)


def test_pixel_base_radius_matches_the_pixel_footprint_variance():
    """A unit-depth disc of radius R has variance R^2 / 4 per axis; a square pixel of width s has s^2 / 12."""
    fx = 500.0
    r = float(pixel_base_radius(fx, fx))
    assert r**2 / 4 == pytest.approx((1 / fx) ** 2 / 12, rel=1e-6)
