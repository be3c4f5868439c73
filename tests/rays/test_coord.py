"""Contraction and sample spacing of unbounded scenes (nerfkit.rays.coord)."""

import jax.numpy as jnp
import numpy as np
import pytest
import reference

from nerfkit.rays import coord
from nerfkit.sampling import occupancy


def test_contract_is_identity_inside_and_maps_space_into_the_ball_of_radius_two():
    rng = np.random.default_rng(0)
    inside = rng.normal(size=(100, 3))
    inside /= np.linalg.norm(inside, axis=-1, keepdims=True) * rng.uniform(1.01, 5, (100, 1))
    np.testing.assert_allclose(coord.contract(jnp.asarray(inside)), inside, atol=1e-7)
    far = rng.normal(size=(100, 3)) * 10 ** rng.uniform(0, 6, (100, 1))
    y = np.asarray(coord.contract(jnp.asarray(far, jnp.float32)))
    n_x, n_y = np.linalg.norm(far, axis=-1), np.linalg.norm(y, axis=-1)
    assert np.all(n_y < 2.0 + 1e-6)
    out = n_x > 1
    np.testing.assert_allclose(n_y[out], 2 - 1 / n_x[out], rtol=1e-5)  # |contract(x)| = 2 - 1/|x|
    np.testing.assert_allclose(y[out] / n_y[out, None], far[out] / n_x[out, None], atol=1e-5)  # same direction


def test_uncontract_inverts_contract():
    x = jnp.asarray(np.random.default_rng(1).normal(size=(200, 3)) * 3, jnp.float32)
    np.testing.assert_allclose(reference.uncontract(coord.contract(x)), x, rtol=2e-4, atol=1e-5)


def test_radial_stretch_is_the_derivative_of_the_inverse_contraction():
    for r in (0.5, 1.2, 1.5, 1.9):
        y = jnp.array([[r, 0.0, 0.0]])
        h = 1e-3
        dx = (reference.uncontract(y + jnp.array([[h, 0, 0]])) - reference.uncontract(y - jnp.array([[h, 0, 0]])))[0, 0] / (2 * h)
        assert float(coord.radial_stretch(y)[0]) == pytest.approx(float(dx), rel=2e-3)


def test_spacing_is_linear_then_disparity_and_inverts():
    t = jnp.array([0.0, 1.0, 2.0, 4.0, 8.0, 100.0])
    s = coord.spacing(t, 2.0)
    np.testing.assert_allclose(s, [0.0, 0.5, 1.0, 1.5, 1.75, 2 - 2 / 100], rtol=1e-6)
    np.testing.assert_allclose(coord.spacing_inverse(s, 2.0), t, rtol=1e-5)


def test_contracted_candidates_are_even_in_t_inside_and_in_disparity_outside():
    t0, t1, cand = occupancy.contracted_candidates(1, 0.0, 1e4, 2.0, 400)
    t0, t1 = np.asarray(t0[0]), np.asarray(t1[0])
    assert cand.all() and np.all(np.diff(t0) > 0)
    np.testing.assert_allclose(t1[:-1], t0[1:], rtol=1e-5)  # contiguous
    inner = t1 <= 2.0
    np.testing.assert_allclose(np.diff(t0[inner]), 2.0 * (2 - 2 / 1e4) / 400, rtol=1e-3)
    outer = t0 > 2.0
    disparity = 1 / t0[outer]
    np.testing.assert_allclose(np.diff(disparity), np.diff(disparity)[0], rtol=2e-3)
    assert t1[-1] == pytest.approx(1e4, rel=1e-3)  # float32 near s = 2


def test_contraction_scale_is_the_cube_root_of_the_jacobian_determinant():
    import jax

    rng = np.random.default_rng(5)
    x = rng.normal(size=(40, 3)) * 10 ** rng.uniform(-1, 2, (40, 1))
    for p in x.astype(np.float32):
        det = abs(float(np.linalg.det(np.asarray(jax.jacfwd(coord.contract)(jnp.asarray(p))))))
        np.testing.assert_allclose(float(coord.contraction_scale(jnp.asarray(p))), det ** (1 / 3), rtol=2e-4)
