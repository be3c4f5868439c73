"""Contraction and sample spacing of unbounded scenes (nerfkit.rays.coord)."""

import jax
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
    rng = np.random.default_rng(5)
    x = rng.normal(size=(40, 3)) * 10 ** rng.uniform(-1, 2, (40, 1))
    for p in x.astype(np.float32):
        det = abs(float(np.linalg.det(np.asarray(jax.jacfwd(coord.contract)(jnp.asarray(p))))))
        np.testing.assert_allclose(float(coord.contraction_scale(jnp.asarray(p))), det ** (1 / 3), rtol=2e-4)


def _ndc_frame(seed: int = 0):
    """A reference camera [3, 4] turned and moved at random, a near plane and slopes."""
    from nerfkit.rays.cameras import look_at

    rng = np.random.default_rng(seed)
    eye = rng.normal(size=3)
    c2w = look_at(eye, eye + rng.normal(size=3))
    return jnp.asarray(c2w[:3, :4], jnp.float32), 0.7, (0.6, 0.45)


def _frustum_points(frame, near, extent, n, rng, depth=(1.0, 1e3)):
    """Points of the frustum in front of `frame` (slopes within extent, depths in near x depth): [n, 3]."""
    z = near * 10 ** rng.uniform(np.log10(depth[0]), np.log10(depth[1]), n)
    q = np.stack([rng.uniform(-1, 1, n) * extent[0] * z, rng.uniform(-1, 1, n) * extent[1] * z, -z], -1)
    f = np.asarray(frame, np.float64)
    return (q @ f[:, :3].T + f[:, 3]).astype(np.float32), q, z


def test_ndc_maps_the_frustum_onto_the_cube_evenly_in_disparity_and_inverts():
    frame, near, extent = _ndc_frame()
    rng = np.random.default_rng(1)
    x, q, z = _frustum_points(frame, near, extent, 500, rng)
    y = np.asarray(coord.ndc(jnp.asarray(x), frame, near, extent))
    assert np.all(np.abs(y) <= 1 + 1e-4)
    np.testing.assert_allclose(y[:, 2], 1 - 2 * near / z, atol=2e-5)  # linear in disparity n / z
    np.testing.assert_allclose(y[:, :2], q[:, :2] / (np.array(extent) * z[:, None]), atol=1e-4)
    near_plane = _frustum_points(frame, near, extent, 50, rng, depth=(1.0, 1.0))[0]
    np.testing.assert_allclose(np.asarray(coord.ndc(jnp.asarray(near_plane), frame, near, extent))[:, 2], -1, atol=1e-5)
    back = np.asarray(coord.ndc_inverse(jnp.asarray(y), frame, near, extent))
    close = z < 100 * near  # float32 loses the far points' depth
    np.testing.assert_allclose(back[close], x[close], rtol=1e-3, atol=1e-3)


def test_ndc_puts_what_no_camera_sees_outside_the_cube():
    frame, near, extent = _ndc_frame(2)
    rng = np.random.default_rng(3)
    f = np.asarray(frame, np.float64)
    nearer = _frustum_points(frame, near, extent, 100, rng, depth=(0.05, 0.99))[0]
    behind = (_frustum_points(frame, near, extent, 100, rng)[1] * [1, 1, -1]) @ f[:, :3].T + f[:, 3]
    wide = _frustum_points(frame, near, (extent[0] * 1.5, extent[1]), 400, rng)
    wide = wide[0][np.abs(wide[1][:, 0] / wide[2]) > extent[0] * 1.01]
    for pts in (nearer, behind, wide):
        y = np.asarray(coord.ndc(jnp.asarray(pts, jnp.float32), frame, near, extent))
        assert np.all(np.isfinite(y)) and np.all(np.abs(y).max(-1) > 1.0)
    at_camera = jnp.asarray(f[None, :, 3], jnp.float32)
    assert np.all(np.abs(np.asarray(coord.ndc(at_camera, frame, near, extent))) == 2.0)


def test_ndc_scale_is_the_cube_root_of_the_jacobian_determinant_and_stretch_its_depth_derivative():
    frame, near, extent = _ndc_frame(4)
    x, _, z = _frustum_points(frame, near, extent, 30, np.random.default_rng(5), depth=(1.0, 50.0))
    for p in x:
        jac = np.asarray(jax.jacfwd(lambda v: coord.ndc(v, frame, near, extent))(jnp.asarray(p)), np.float64)
        np.testing.assert_allclose(float(coord.ndc_scale(jnp.asarray(p), frame, near, extent)),
                                   abs(np.linalg.det(jac)) ** (1 / 3), rtol=2e-3)
    for y3 in (-0.9, 0.0, 0.5, 0.9):
        depth = lambda s: 2 * near / (1 - s)  # noqa: E731
        h = 1e-4
        assert float(coord.ndc_stretch(jnp.array([[0.0, 0.0, y3]]))[0]) == pytest.approx(
            (depth(y3 + h) - depth(y3 - h)) / (2 * h) / near, rel=1e-4)
