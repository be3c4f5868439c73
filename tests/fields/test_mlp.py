"""Tests for the positional-encoded NeRF MLP field (nerfkit.fields.mlp)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.core.config import FieldConfig
from nerfkit.fields.mlp import MLPField

SMALL = FieldConfig(depth=4, width=32, l_xyz=4, l_dir=2)


def inputs(seed, shape=(5, 7)):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.2, 1.2, size=(*shape, 3)).astype(np.float32)
    d = rng.normal(size=(*shape, 3))
    d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).astype(np.float32)
    return jnp.asarray(x), jnp.asarray(d)


def with_sigma_bias(params, b):
    """Shift the density logit so that a good share of sigma is positive (relu not all 0)."""
    return {**params, "sigma": {**params["sigma"], "b": jnp.full_like(params["sigma"]["b"], b)}}


@pytest.fixture(scope="module")
def field_and_params():
    field = MLPField(SMALL)
    return field, with_sigma_bias(field.init(jax.random.PRNGKey(0)), 0.1)


def test_output_shapes_and_ranges(field_and_params):
    field, params = field_and_params
    x, d = inputs(0)
    rgb, sigma = field(params, x, d)
    assert rgb.shape == (5, 7, 3) and sigma.shape == (5, 7)
    assert rgb.dtype == sigma.dtype == jnp.float32
    rgb, sigma = np.asarray(rgb), np.asarray(sigma)
    assert np.all(sigma >= 0)
    assert np.all((rgb > 0) & (rgb < 1))
    assert np.any(sigma > 0) and np.ptp(rgb) > 1e-3  # not a degenerate constant output


def test_density_equals_sigma_of_call(field_and_params):
    field, params = field_and_params
    x, d = inputs(1)
    _, sigma = field(params, x, d)
    dens = field.density(params, x)
    assert dens.shape == sigma.shape
    np.testing.assert_allclose(np.asarray(dens), np.asarray(sigma), rtol=1e-6, atol=1e-7)


def test_sigma_is_relu_clamped():
    # A very negative density bias makes every sigma exactly 0 (not negative).
    field = MLPField(SMALL)
    params = with_sigma_bias(field.init(jax.random.PRNGKey(1)), -1e3)
    x, d = inputs(2)
    _, sigma = field(params, x, d)
    np.testing.assert_array_equal(np.asarray(sigma), 0.0)


def test_parameter_shapes_with_encoding():
    field = MLPField(SMALL)
    params = field.init(jax.random.PRNGKey(0))
    x_dim, d_dim = 3 * (1 + 2 * 4), 3 * (1 + 2 * 2)
    assert params["trunk"][0]["w"].shape == (x_dim, 32)
    assert params["view"]["w_d"].shape == (d_dim, 16)
    assert params["sigma"]["w"].shape == (32, 1)
    assert params["rgb"]["w"].shape == (16, 3)
    # Zero biases, Glorot-uniform weights within sqrt(6 / (fan_in + fan_out)).
    for layer in params["trunk"]:
        np.testing.assert_array_equal(np.asarray(layer["b"]), 0.0)
    w0 = np.asarray(params["trunk"][0]["w"])
    limit = np.sqrt(6.0 / (x_dim + 32))
    assert np.abs(w0).max() <= limit and np.abs(w0).max() > 0.8 * limit


def test_without_positional_encoding_first_layer_takes_3_inputs():
    cfg = dataclasses.replace(SMALL, pe=False)
    field = MLPField(cfg)
    params = field.init(jax.random.PRNGKey(0))
    assert params["trunk"][0]["w"].shape == (3, 32)
    assert params["trunk"][field.skip]["w_skip"].shape == (3, 32)
    assert params["view"]["w_d"].shape == (3, 16)
    x, d = inputs(3)
    rgb, sigma = field(params, x, d)
    assert rgb.shape == (5, 7, 3) and sigma.shape == (5, 7)


@pytest.mark.parametrize("depth, skip", [(8, 5), (4, 3), (3, 2), (2, None), (1, None)])
def test_skip_layer_index(depth, skip):
    field = MLPField(dataclasses.replace(SMALL, depth=depth))
    assert field.skip == skip
    params = field.init(jax.random.PRNGKey(0))
    assert len(params["trunk"]) == depth
    has_skip = [i for i, layer in enumerate(params["trunk"]) if "w_skip" in layer]
    assert has_skip == ([] if skip is None else [skip])
    if skip is not None:
        assert params["trunk"][skip]["w_skip"].shape == (field.x_dim, SMALL.width)


@pytest.mark.parametrize("depth", [8, 4])
def test_changing_skip_weights_changes_output(depth):
    field = MLPField(dataclasses.replace(SMALL, depth=depth))
    params = with_sigma_bias(field.init(jax.random.PRNGKey(2)), 0.1)
    x, d = inputs(4)
    rgb0, sigma0 = field(params, x, d)
    trunk = list(params["trunk"])
    trunk[field.skip] = {**trunk[field.skip], "w_skip": trunk[field.skip]["w_skip"] * 0.0}
    rgb1, sigma1 = field({**params, "trunk": trunk}, x, d)
    assert np.abs(np.asarray(rgb0) - np.asarray(rgb1)).max() > 1e-4
    assert np.abs(np.asarray(sigma0) - np.asarray(sigma1)).max() > 1e-4


def test_view_direction_broadcast_equals_repeated_directions(field_and_params):
    field, params = field_and_params
    x, _ = inputs(5, shape=(4, 6))
    _, d_ray = inputs(6, shape=(4, 1))
    rgb_b, sigma_b = field(params, x, d_ray)
    rgb_r, sigma_r = field(params, x, jnp.broadcast_to(d_ray, x.shape))
    assert rgb_b.shape == rgb_r.shape == (4, 6, 3)
    # Same arithmetic per element; allow float32 reassociation inside the matmuls.
    np.testing.assert_allclose(np.asarray(rgb_b), np.asarray(rgb_r), rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(np.asarray(sigma_b), np.asarray(sigma_r))


def test_colour_depends_on_view_direction_only_when_enabled():
    x, d1 = inputs(7)
    _, d2 = inputs(8)
    field = MLPField(SMALL)
    params = field.init(jax.random.PRNGKey(3))
    rgb1, s1 = field(params, x, d1)
    rgb2, s2 = field(params, x, d2)
    assert np.abs(np.asarray(rgb1) - np.asarray(rgb2)).max() > 1e-4
    np.testing.assert_array_equal(np.asarray(s1), np.asarray(s2))  # density never sees d
    field = MLPField(dataclasses.replace(SMALL, viewdirs=False))
    params = field.init(jax.random.PRNGKey(3))
    assert "view" not in params and params["rgb"]["w"].shape == (32, 3)
    rgb1, _ = field(params, x, d1)
    rgb2, _ = field(params, x, d2)
    np.testing.assert_array_equal(np.asarray(rgb1), np.asarray(rgb2))


def test_field_is_a_pure_function_of_params_and_jittable(field_and_params):
    field, params = field_and_params
    x, d = inputs(9)
    eager = field(params, x, d)
    jitted = jax.jit(field.__call__)(params, x, d)
    for a, b in zip(eager, jitted):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-6)
    other = field.init(jax.random.PRNGKey(99))
    assert not np.allclose(np.asarray(field(other, x, d)[0]), np.asarray(eager[0]))
