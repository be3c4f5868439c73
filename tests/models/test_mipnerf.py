"""mip-NeRF's model (nerfkit.models.mipnerf.MipNeRFModel) and how cones reach the models: the renderer passes each
camera's pixel radius, the training step each frame's (cameras.ray_table)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.presets import preset
from nerfkit.models.mipnerf import MipNeRFModel
from nerfkit.models.registry import build_model
from nerfkit.rays.cameras import Camera, look_at, ray_table
from nerfkit.rays.frustum import pixel_base_radius
from nerfkit.render.chunked import Renderer


def _mip_config():
    cfg = preset("mipnerf")
    cfg.field.depth, cfg.field.width, cfg.field.l_xyz = 2, 32, 8
    cfg.sampler.n_samples, cfg.sampler.n_importance = 64, 64
    return cfg


class _SlabField:
    """sigma = 50 where the frustum's mean has |z| < 0.1 (a slab), grey; records the covariances seen."""

    def embedding(self, params, image_idx):
        return None

    def __call__(self, params, mean, d, emb=None, footprint=None):
        sigma = jnp.where(jnp.abs(mean[..., 2]) < 0.1, 50.0, 0.0)
        return jnp.full(mean.shape, 0.5), sigma


def test_mipnerf_finds_a_slab_and_resamples_its_fine_frustums_there():
    """Rays from z = 4 straight down meet the slab |z| < 0.1 at t = 3.9: the depth of the fine pass is the
    slab's front face within a coarse interval, weights sum to opacity, and the resampled edges (from the
    blurred coarse weights) crowd around the slab."""
    model = MipNeRFModel(_mip_config())
    model.field = _SlabField()
    n = 16
    o = jnp.tile(jnp.array([[0.0, 0.0, 4.0]]), (n, 1)) + jnp.asarray(np.random.default_rng(0).normal(0, .1, (n, 3)))
    o = o.at[:, 2].set(4.0)
    d = jnp.tile(jnp.array([[0.0, 0.0, -1.0]]), (n, 1))
    out = jax.jit(model.render_rays, static_argnums=(5,))({"field": None}, {}, o, d, jax.random.PRNGKey(1), True,
                                                          None, jnp.full(n, 0.01))
    np.testing.assert_allclose(out["weights"].sum(-1), out["opacity"], atol=1e-6)
    assert np.all(np.asarray(out["opacity"]) > 0.99)
    np.testing.assert_allclose(out["depth_normalized"], 3.9, atol=4.0 / 64)
    t = np.asarray(out["edges"])
    assert t.shape == (n, 65) and np.all(np.diff(t, axis=-1) >= 0)
    assert np.mean((t > 3.7) & (t < 4.3)) > 0.5  # 15% of [2, 6] holds most fine edges
    assert "coarse" in out and out["coarse"]["edges"].shape == (n, 65)


def test_mipnerf_trains_on_its_losses():
    """Fine MSE + 0.1 coarse MSE goes down over a few Adam steps on a fixed batch of cones."""
    import optax

    cfg = _mip_config()
    model = build_model(cfg)
    params, aux = model.init(jax.random.PRNGKey(0))
    rng = np.random.default_rng(1)
    o = jnp.asarray(rng.normal(0, 0.2, (64, 3)) + [0, 0, 4], jnp.float32)
    d = jnp.asarray(np.tile([0.0, 0.0, -1.0], (64, 1)), jnp.float32)
    target = jnp.asarray(rng.uniform(0, 1, (64, 3)), jnp.float32)
    opt = optax.adam(5e-3)
    state = opt.init(params)

    @jax.jit
    def step(p, s, k):
        (loss, _), g = jax.value_and_grad(
            lambda q: model.losses(model.render_rays(q, aux, o, d, k, True, None, jnp.full(64, 2e-3)), target),
            has_aux=True)(p)
        u, s = opt.update(g, s, p)
        return optax.apply_updates(p, u), s, loss

    losses = []
    for i in range(30):
        params, state, loss = step(params, state, jax.random.PRNGKey(i))
        losses.append(float(loss))
    assert np.all(np.isfinite(losses)) and np.mean(losses[-5:]) < 0.7 * np.mean(losses[:5])


class _RadiusProbe:
    """A model whose every output is the cone radius it was given."""

    def render_rays(self, params, aux, o, d, key, train, image_idx=None, radii=None):
        r = jnp.zeros(o.shape[0]) if radii is None else radii
        return {"rgb": jnp.tile(r[:, None], (1, 3)), "depth": r, "depth_normalized": r, "opacity": r}


def test_renderer_casts_cones_of_the_cameras_pixel_size():
    cam = Camera.pinhole(12, 10, 20.0)
    c2w = look_at(np.array([0.0, -4.0, 1.0]), np.zeros(3))
    for camera in (cam, cam.scaled(0.5)):
        out = Renderer(_RadiusProbe(), chunk=32).render_camera(None, None, c2w, camera)
        np.testing.assert_allclose(out["depth"], 2 / np.sqrt(12) / camera.fx, rtol=1e-6)
    table = ray_table([cam, cam.scaled(0.5)])
    np.testing.assert_allclose(table["radius"], [pixel_base_radius(20.0, 20.0), pixel_base_radius(10.0, 10.0)],
                               rtol=1e-6)
    np.testing.assert_allclose(table["radius"][1], 2 * table["radius"][0], rtol=1e-6)
