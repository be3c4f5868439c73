"""Tests of the real spherical-harmonics encoding (nerfkit.encoding.sh)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.encoding.sh import sh_encode

SH = jax.jit(sh_encode, static_argnums=1)


def sphere_quadrature(n_theta=12, n_phi=24):
    """Product rule on S^2: Gauss-Legendre in z = cos(theta) x uniform in phi.

    Exact for polynomials in (x, y, z) of total degree <= min(2 n_theta - 1, n_phi - 1);
    products Y_i Y_j of bands <= 4 have degree <= 8.
    Returns directions [n, 3] (float64) and weights [n] summing to 4 pi.
    """
    z, wz = np.polynomial.legendre.leggauss(n_theta)
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    z, phi = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1 - z**2)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), z], -1).reshape(-1, 3)
    w = np.repeat(wz, n_phi) * (2 * np.pi / n_phi)
    return d, w


def real_sh_reference(d, degree):
    """Real SH with the Condon-Shortley phase, ordered l = 0.., m = -l..l (float64):

    Y_lm = sqrt(2) K_l^|m| P_l^|m|(z) * (cos(m phi) if m > 0 else sin(|m| phi)),  m != 0
    Y_l0 = K_l^0 P_l^0(z),   K_l^m = sqrt((2l + 1) / (4 pi) * (l - m)! / (l + m)!),
    with P_l^m the associated Legendre functions including (-1)^m (standard recursion).
    """
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    phi = np.arctan2(y, x)
    st = np.sqrt(np.maximum(1 - z**2, 0))
    p = {}
    for m in range(degree):
        p[(m, m)] = (-1) ** m * math.prod(range(1, 2 * m, 2)) * st**m
        if m + 1 < degree:
            p[(m + 1, m)] = z * (2 * m + 1) * p[(m, m)]
        for l in range(m + 2, degree):
            p[(l, m)] = ((2 * l - 1) * z * p[(l - 1, m)] - (l + m - 1) * p[(l - 2, m)]) / (l - m)
    out = []
    for l in range(degree):
        for m in range(-l, l + 1):
            am = abs(m)
            k = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - am) / math.factorial(l + am))
            if m == 0:
                out.append(k * p[(l, 0)])
            elif m > 0:
                out.append(math.sqrt(2) * k * p[(l, am)] * np.cos(am * phi))
            else:
                out.append(math.sqrt(2) * k * p[(l, am)] * np.sin(am * phi))
    return np.stack(out, -1)


def test_constant_band_and_shape():
    d = jnp.asarray(np.random.default_rng(0).standard_normal((7, 3)), jnp.float32)
    d = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
    y = SH(d, 4)
    assert y.shape == (7, 16) and y.dtype == jnp.float32
    # Y_0 = 1 / (2 sqrt(pi)) = 0.28209479..., rounded to float32 (ulp 3e-8).
    np.testing.assert_array_equal(y[:, 0], np.float32(0.28209479177387814))
    np.testing.assert_allclose(y[:, 0], 0.28209479, rtol=0, atol=3e-8)
    assert abs(0.28209479177387814 - 1 / (2 * math.sqrt(math.pi))) < 1e-15
    for deg in range(1, 6):
        assert SH(d, deg).shape == (7, deg**2)
        np.testing.assert_array_equal(SH(d, deg), SH(d, 5)[:, : deg**2])  # nested bands
    with pytest.raises(ValueError):
        sh_encode(d, 6)


@pytest.mark.parametrize("degree", [4, 5])
def test_orthonormal_by_exact_quadrature(degree):
    # The quadrature is exact for these polynomials, so the only error is float32
    # rounding of Y (~1e-7 relative): |G - I| < 1e-5.
    d, w = sphere_quadrature(n_theta=12, n_phi=24)
    y = np.asarray(SH(jnp.asarray(d, jnp.float32), degree), np.float64)
    gram = (y * w[:, None]).T @ y
    np.testing.assert_allclose(gram, np.eye(degree**2), atol=1e-5)


def test_orthonormal_by_monte_carlo():
    # 2^18 uniform directions; each Gram entry's standard error is
    # 4 pi std(Y_i Y_j) / sqrt(n) < 0.01 here, so 0.05 is a > 5-sigma tolerance.
    n = 1 << 18
    d = np.random.default_rng(1).standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    y = np.asarray(SH(jnp.asarray(d, jnp.float32), 4), np.float64)
    gram = 4 * np.pi * (y.T @ y) / n
    np.testing.assert_allclose(gram, np.eye(16), atol=0.05)


def test_matches_condon_shortley_real_sh():
    # Independent derivation via associated Legendre functions: same values, ordering
    # and signs as tiny-cuda-nn (whose constants include the Condon-Shortley phase).
    d = np.random.default_rng(2).standard_normal((512, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    np.testing.assert_allclose(SH(jnp.asarray(d, jnp.float32), 5), real_sh_reference(d, 5), atol=2e-6)
    # A few tiny-cuda-nn values at d = +z: Y_2 = sqrt(3)/(2 sqrt(pi)), Y_6 = sqrt(5)/(2 sqrt(pi)).
    y = np.asarray(SH(jnp.array([[0.0, 0.0, 1.0]]), 4))[0]
    np.testing.assert_allclose(y[[0, 2, 6, 12]], [0.28209479, 0.48860251, 0.63078313, 0.74635267], atol=1e-7)
    assert np.all(y[[1, 3, 4, 5, 7, 8, 9, 10, 11, 13, 14, 15]] == 0)
