"""The seams of models/base.py: every kind of field takes one call signature (Field)."""

from __future__ import annotations

import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.core.presets import preset
from nerfkit.fields.mlp import MLPField
from nerfkit.fields.ngp import HashGridField
from nerfkit.models.baked.model import BakedField
from nerfkit.models.base import Field

KINDS = {"mipnerf": MLPField, "ngp": HashGridField}  # the kinds that read a footprint


def _parameters(fn) -> list[str]:
    return [p for p in inspect.signature(fn).parameters if p != "self"]


@pytest.mark.parametrize("cls", [MLPField, HashGridField, BakedField])
def test_every_field_has_the_one_signature(cls):
    assert _parameters(cls.__call__) == _parameters(Field.__call__) == ["params", "x", "d", "emb", "footprint"]
    assert _parameters(cls.density) == _parameters(Field.density) == ["params", "x", "footprint"]
    assert inspect.signature(cls.__call__).parameters["footprint"].default is None


@pytest.mark.parametrize("name", sorted(KINDS))
def test_footprint_none_is_a_point_and_a_footprint_is_read(name):
    """footprint=None gives the point encoding; each kind's footprint (mip: a covariance [..., 3], ngp
    --antialias: a std [...]) changes what it returns, and density agrees with the call."""
    cfg = preset(name)
    cfg.field.antialias = name == "ngp"
    cfg.field.depth, cfg.field.width = 2, 16
    field = KINDS[name](cfg.field)
    assert isinstance(field, Field)
    params = field.init(jax.random.PRNGKey(0))
    x = jax.random.uniform(jax.random.PRNGKey(1), (32, 3), minval=-0.5, maxval=0.5)
    d = x / jnp.linalg.norm(x, axis=-1, keepdims=True)
    big = jnp.full((32, 3), 0.05) if name != "ngp" else jnp.full((32,), 0.05)
    rgb0, sigma0 = field(params, x, d)
    rgb1, sigma1 = field(params, x, d, None, footprint=big)
    np.testing.assert_allclose(field.density(params, x, big), sigma1, rtol=1e-6)
    np.testing.assert_allclose(field.density(params, x), sigma0, rtol=1e-6)
    assert not np.allclose(np.asarray(rgb0), np.asarray(rgb1)) or not np.allclose(sigma0, sigma1)
