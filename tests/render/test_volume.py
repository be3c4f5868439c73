"""Tests for volume rendering (nerfkit.render.volume).

Reference values are computed in float64 numpy from the float32 inputs. The JAX code runs
in float32: a cumulative sum of N optical depths of size O(1) carries ~N * 2^-24 relative
error, so weights / opacities are compared with atol 1e-5 for N <= 64.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.render import volume as render

# Jitted once per shape: op-by-op dispatch of these small graphs is slow on a shared CPU.
composite = jax.jit(render.composite)
compositing_weights = jax.jit(render.compositing_weights)
sample_intervals = jax.jit(render.sample_intervals)
volume_render = jax.jit(render.volume_render)
packed_compositing_weights = jax.jit(render.packed_compositing_weights)
packed_composite = jax.jit(render.packed_composite, static_argnums=(4,))

ATOL = 1e-5


def random_samples(seed, r=6, n=48, near=2.0, far=6.0):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(near, far, size=(r, n)), axis=-1).astype(np.float32)
    sigma = rng.exponential(2.0, size=(r, n)).astype(np.float32)
    sigma[rng.uniform(size=(r, n)) < 0.3] = 0.0  # some empty samples
    rgb = rng.uniform(size=(r, n, 3)).astype(np.float32)
    dir_norm = rng.uniform(1.0, 1.3, size=r).astype(np.float32)
    return t, sigma, rgb, dir_norm


def reference_weights(sigma, delta):
    """w_i = T_i alpha_i with T_i = prod_{j<i} (1 - alpha_j) (float64)."""
    alpha = 1.0 - np.exp(-np.asarray(sigma, np.float64) * np.asarray(delta, np.float64))
    trans = np.cumprod(np.concatenate([np.ones_like(alpha[..., :1]), 1.0 - alpha[..., :-1]], axis=-1), axis=-1)
    return trans * alpha, trans, alpha


def test_sample_intervals():
    t = jnp.array([[2.0, 2.5, 3.5, 5.0]])
    np.testing.assert_allclose(np.asarray(sample_intervals(t, 0.25)), [[0.5, 1.0, 1.5, 0.25]])


def test_weights_sum_to_one_minus_exp_total_optical_depth():
    t, sigma, _, _ = random_samples(0)
    delta = np.asarray(sample_intervals(jnp.asarray(t), 0.1))
    w = np.asarray(compositing_weights(jnp.asarray(sigma), jnp.asarray(delta)))
    assert np.all(w >= 0)
    opacity = 1.0 - np.exp(-np.sum(sigma.astype(np.float64) * delta, axis=-1))
    np.testing.assert_allclose(w.sum(-1), opacity, atol=ATOL)
    assert np.all(w.sum(-1) <= 1.0 + 1e-6)


def test_transmittance_is_cumprod_of_one_minus_alpha():
    t, sigma, _, _ = random_samples(1)
    delta = np.asarray(sample_intervals(jnp.asarray(t), 0.1))
    w = np.asarray(compositing_weights(jnp.asarray(sigma), jnp.asarray(delta)))
    w_ref, trans, alpha = reference_weights(sigma, delta)
    np.testing.assert_allclose(w, w_ref, atol=ATOL)
    # T_i recovered from the weights where alpha is not tiny.
    ok = alpha > 1e-2
    np.testing.assert_allclose(w[ok] / alpha[ok], trans[ok], atol=1e-4)  # ATOL / alpha_min


def test_volume_render_matches_reference_and_scales_by_direction_norm():
    t, sigma, rgb, dir_norm = random_samples(2)
    last = 4.0 / t.shape[1]
    bg = jnp.array([0.2, 0.5, 0.9])
    out = volume_render(jnp.asarray(sigma), jnp.asarray(rgb), jnp.asarray(t), jnp.asarray(dir_norm), last, bg)
    delta = np.concatenate([np.diff(t, axis=-1), np.full((t.shape[0], 1), last)], axis=-1) * dir_norm[:, None]
    w, _, _ = reference_weights(sigma, delta)
    acc = w.sum(-1)
    np.testing.assert_allclose(np.asarray(out["weights"]), w, atol=ATOL)
    np.testing.assert_allclose(np.asarray(out["opacity"]), acc, atol=ATOL)
    np.testing.assert_allclose(np.asarray(out["rgb"]), (w[..., None] * rgb).sum(-2) + (1 - acc)[:, None] * np.asarray(bg), atol=ATOL)
    np.testing.assert_allclose(np.asarray(out["depth"]), (w * t).sum(-1), atol=6 * ATOL)  # t up to 6
    np.testing.assert_allclose(np.asarray(out["depth_normalized"]), (w * t).sum(-1) / acc, rtol=1e-4)
    # |d| enters only through sigma * delta: doubling |d| equals doubling sigma.
    a = volume_render(jnp.asarray(sigma), jnp.asarray(rgb), jnp.asarray(t), 2 * jnp.asarray(dir_norm), last, bg)
    b = volume_render(2 * jnp.asarray(sigma), jnp.asarray(rgb), jnp.asarray(t), jnp.asarray(dir_norm), last, bg)
    np.testing.assert_allclose(np.asarray(a["rgb"]), np.asarray(b["rgb"]), atol=1e-6)
    assert not np.allclose(np.asarray(a["opacity"]), np.asarray(out["opacity"]), atol=1e-3)


@pytest.mark.parametrize("perturbed", [False, True])
def test_opaque_slab_renders_its_colour_at_its_front_depth(perturbed):
    near, far, n, r = 2.0, 6.0, 128, 4
    spacing = (far - near) / n
    if perturbed:
        rng = np.random.default_rng(3)
        t = near + (np.arange(n) + rng.uniform(size=(r, n))) * spacing
    else:
        t = np.broadcast_to(near + (np.arange(n) + 0.5) * spacing, (r, n))
    t = t.astype(np.float32)
    t0, t1 = 3.3, 4.1
    inside = (t >= t0) & (t <= t1)
    # sigma delta >= 1e4 * ~0.03 = 300: alpha = 1 - e^-300 = 1 in float32, T = 0 behind it.
    sigma = np.where(inside, 1e4, 0.0).astype(np.float32)
    slab_rgb, other_rgb = np.array([0.9, 0.2, 0.4]), np.array([0.1, 0.8, 0.3])
    rgb = np.where(inside[..., None], slab_rgb, other_rgb).astype(np.float32)
    bg = jnp.ones(3)
    out = volume_render(jnp.asarray(sigma), jnp.asarray(rgb), jnp.asarray(t), jnp.ones(r), spacing, bg)
    np.testing.assert_allclose(np.asarray(out["opacity"]), 1.0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(out["rgb"]), np.broadcast_to(slab_rgb, (r, 3)), atol=1e-6)
    # All weight on the first sample inside the slab: depth is that sample's t. With bin
    # midpoints it lies within one spacing behind t0 (half on average); with one jittered
    # sample per bin, the bin holding t0 may have its sample before t0 and the next bin's
    # sample can be up to two spacings behind t0.
    first = t[np.arange(r), np.argmax(inside, axis=-1)]
    depth = np.asarray(out["depth"])
    np.testing.assert_allclose(depth, first, atol=1e-6)
    assert np.all((depth >= t0) & (depth < t0 + (2 if perturbed else 1) * spacing))
    np.testing.assert_allclose(np.asarray(out["depth_normalized"]), first, atol=1e-6)


def test_slab_starting_on_a_bin_edge_gives_depth_half_a_spacing_behind():
    near, far, n = 2.0, 6.0, 64
    spacing = (far - near) / n
    t = (near + (np.arange(n) + 0.5) * spacing).astype(np.float32)[None]
    t0 = near + 20 * spacing  # a bin edge: the first midpoint inside is t0 + spacing / 2
    sigma = np.where(t >= t0, 1e4, 0.0).astype(np.float32)
    out = volume_render(jnp.asarray(sigma), jnp.ones((1, n, 3)), jnp.asarray(t), jnp.ones(1), spacing, jnp.zeros(3))
    np.testing.assert_allclose(np.asarray(out["depth"]), t0 + 0.5 * spacing, atol=1e-6)


def test_empty_space_renders_background_with_zero_opacity():
    t, _, rgb, dir_norm = random_samples(4)
    bg = jnp.array([0.3, 0.6, 0.1])
    out = volume_render(jnp.zeros(t.shape), jnp.asarray(rgb), jnp.asarray(t), jnp.asarray(dir_norm), 0.1, bg)
    np.testing.assert_array_equal(np.asarray(out["opacity"]), 0.0)
    np.testing.assert_array_equal(np.asarray(out["weights"]), 0.0)
    np.testing.assert_allclose(np.asarray(out["rgb"]), np.broadcast_to(np.asarray(bg), (t.shape[0], 3)), atol=1e-7)
    np.testing.assert_array_equal(np.asarray(out["depth"]), 0.0)
    # No hit: the normalised depth reports the far end (the last sample).
    np.testing.assert_array_equal(np.asarray(out["depth_normalized"]), t[:, -1])


def test_finite_last_interval_keeps_sparse_rays_transparent():
    # One sample of density 1 on the last interval only: opacity 1 - exp(-sigma * last).
    t = jnp.linspace(2.0, 6.0, 8)[None]
    sigma = jnp.zeros((1, 8)).at[0, -1].set(1.0)
    out = volume_render(sigma, jnp.ones((1, 8, 3)), t, jnp.ones(1), 0.5, jnp.zeros(3))
    np.testing.assert_allclose(np.asarray(out["opacity"]), 1 - np.exp(-0.5), rtol=1e-6)


# --- packed form ---------------------------------------------------------------------------


def pack(sigma, delta, rgb, t, seed=0):
    """Lay dense samples [R, N] out as a flat list sorted by ray, with invalid padding.

    Padding (valid=False, garbage values) is inserted at the start of a ray's run, in the
    middle of runs, and at the end of the list; ray 0 contributes no samples except padding.
    Returns flat arrays and the dense mask of which samples are present.
    """
    rng = np.random.default_rng(seed)
    r, n = sigma.shape
    cols = {"sigma": [], "delta": [], "rgb": [], "t": [], "ray": [], "valid": []}

    def add(s, d, c, tt, ray, valid):
        for key, v in zip(cols, (s, d, c, tt, ray, valid)):
            cols[key].append(v)

    present = np.ones((r, n), bool)
    present[0] = False  # ray 0 only gets padding
    for ray in range(r):
        if ray % 2 == 0:  # padding before the ray's first valid sample
            add(50.0, 1.0, np.ones(3), 0.0, ray, False)
        for k in range(n):
            if present[ray, k]:
                add(sigma[ray, k], delta[ray, k], rgb[ray, k], t[ray, k], ray, True)
            if rng.uniform() < 0.2:  # padding inside the run
                add(rng.uniform(0, 100), 1.0, rng.uniform(size=3), 3.0, ray, False)
    for _ in range(5):  # trailing padding, attributed to the last ray
        add(100.0, 1.0, np.ones(3), 9.0, r - 1, False)
    flat = {k: np.asarray(v) for k, v in cols.items()}
    flat["sigma"] = flat["sigma"].astype(np.float32)
    flat["delta"] = flat["delta"].astype(np.float32)
    flat["rgb"] = flat["rgb"].astype(np.float32)
    flat["t"] = flat["t"].astype(np.float32)
    flat["ray"] = flat["ray"].astype(np.int32)
    return flat, present


def dense_and_packed(seed, min_transmittance=0.0):
    t, sigma, rgb, dir_norm = random_samples(seed, r=5, n=24)
    delta = np.asarray(sample_intervals(jnp.asarray(t), 0.2)) * dir_norm[:, None]
    flat, present = pack(sigma, delta, rgb, t, seed)
    sigma_d = np.where(present, sigma, 0.0)  # absent samples have no density in the dense layout
    r = t.shape[0]
    w_dense = np.asarray(compositing_weights(jnp.asarray(sigma_d), jnp.asarray(delta)))
    w_packed = np.asarray(packed_compositing_weights(
        jnp.asarray(flat["sigma"]), jnp.asarray(flat["delta"]), jnp.asarray(flat["ray"]),
        jnp.asarray(flat["valid"]), min_transmittance))
    return t, sigma_d, delta, rgb, flat, present, w_dense, w_packed


def test_packed_weights_equal_dense_weights():
    t, sigma_d, delta, rgb, flat, present, w_dense, w_packed = dense_and_packed(0)
    valid = flat["valid"]
    np.testing.assert_array_equal(w_packed[~valid], 0.0)
    np.testing.assert_allclose(w_packed[valid], w_dense[present], atol=ATOL)
    assert w_dense[present].max() > 0.05  # a meaningful comparison


def test_packed_composite_equals_dense_composite():
    t, sigma_d, delta, rgb, flat, present, w_dense, w_packed = dense_and_packed(1)
    r = t.shape[0]
    bg = jnp.array([0.7, 0.1, 0.4])
    dense = composite(jnp.asarray(w_dense), jnp.asarray(rgb), jnp.asarray(t), bg)
    packed = packed_composite(jnp.asarray(w_packed), jnp.asarray(flat["rgb"]), jnp.asarray(flat["t"]),
                              jnp.asarray(flat["ray"]), r, bg, 6.0)
    for key, tol in (("rgb", ATOL), ("opacity", ATOL), ("depth", 6 * ATOL)):
        assert packed[key].shape == dense[key].shape
        np.testing.assert_allclose(np.asarray(packed[key]), np.asarray(dense[key]), atol=tol, err_msg=key)
    # Ray 0 has only padding: background, opacity 0.
    np.testing.assert_array_equal(np.asarray(packed["opacity"])[0], 0.0)
    np.testing.assert_allclose(np.asarray(packed["rgb"])[0], np.asarray(bg), atol=1e-7)
    hit = np.asarray(dense["opacity"]) > 1e-3
    np.testing.assert_allclose(np.asarray(packed["depth_normalized"])[hit],
                               np.asarray(dense["depth_normalized"])[hit], rtol=1e-4)


def test_median_depth_is_the_surface_behind_a_soft_veil_where_the_expected_depth_is_neither():
    """A ray through a veil of opacity 0.4 at t = 3 onto an opaque wall at t = 5: its running opacity
    reaches half its opacity (1/2) at the wall, so the median depth is 5, while the expected depth,
    0.4 * 3 + 0.6 * 5 = 4.2, lies on neither. A ray through a soft surface spread over t = 3, 3.5, 4
    (opacity 0.2 each, 0.6 in all) has its median in the middle, 3.5, not at the far end where it
    turns half opaque; a ray that hits nothing gets the far end."""
    t = jnp.asarray(np.linspace(2.0, 6.0, 9, dtype=np.float32))  # 2, 2.5, ..., 6
    w = np.zeros((3, 9), np.float32)
    w[0, 2], w[0, 6] = 0.4, 0.6  # the veil at t = 3, the wall at t = 5 takes what is left
    w[1, 2:5] = 0.2  # the soft surface
    out = composite(jnp.asarray(w), jnp.ones((3, 9, 3)), jnp.broadcast_to(t, (3, 9)), jnp.zeros(3))
    np.testing.assert_allclose(np.asarray(out["depth_median"]), [5.0, 3.5, 6.0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(out["depth_normalized"])[0], 4.2, atol=1e-5)
    ray = jnp.repeat(jnp.arange(3, dtype=jnp.int32), 9)
    packed = packed_composite(jnp.asarray(w).reshape(-1), jnp.ones((27, 3)), jnp.tile(t, 3), ray, 3,
                              jnp.zeros(3), 6.0)
    np.testing.assert_allclose(np.asarray(packed["depth_median"]), [5.0, 3.5, 6.0], atol=1e-6)


def test_packed_median_depth_equals_dense():
    t, sigma_d, delta, rgb, flat, present, w_dense, w_packed = dense_and_packed(2)
    r = t.shape[0]
    dense = composite(jnp.asarray(w_dense), jnp.asarray(rgb), jnp.asarray(t), jnp.zeros(3))
    packed = packed_composite(jnp.asarray(w_packed), jnp.asarray(flat["rgb"]), jnp.asarray(flat["t"]),
                              jnp.asarray(flat["ray"]), r, jnp.zeros(3), 6.0)
    hit = np.asarray(dense["opacity"]) > 1e-6
    assert hit.sum() == r - 1  # every ray but the empty ray 0
    np.testing.assert_allclose(np.asarray(packed["depth_median"])[hit], np.asarray(dense["depth_median"])[hit])
    # the median is a sample's own t: the first at which the running opacity reaches half the ray's
    cum = np.cumsum(w_dense, axis=1)
    for k in np.flatnonzero(hit):
        j = np.argmax(cum[k] >= 0.5 * cum[k, -1])
        assert np.asarray(dense["depth_median"])[k] == t[k, j]
    np.testing.assert_array_equal(np.asarray(packed["depth_median"])[~hit], 6.0)


def test_packed_depth_normalized_of_empty_ray_matches_dense():
    t = jnp.linspace(2.0, 6.0, 4)
    w = jnp.zeros(4)
    dense = composite(w[None], jnp.ones((1, 4, 3)), t[None], jnp.zeros(3))
    packed = packed_composite(w, jnp.ones((4, 3)), t, jnp.zeros(4, jnp.int32), 1, jnp.zeros(3), t[-1])
    np.testing.assert_allclose(np.asarray(packed["depth_normalized"]), np.asarray(dense["depth_normalized"]))


def test_min_transmittance_zeroes_weights_after_transmittance_drops():
    t, sigma_d, delta, rgb, flat, present, w_dense, _ = dense_and_packed(2)
    m = 0.2
    *_, w_packed = dense_and_packed(2, min_transmittance=m)
    _, trans, _ = reference_weights(sigma_d, delta)
    expected = np.where(trans >= m, w_dense, 0.0)[present]
    # Samples with T within float32 noise of the threshold could go either way: skip them.
    clear = np.abs(trans[present] - m) > 1e-5
    valid = flat["valid"]
    np.testing.assert_allclose(w_packed[valid][clear], expected[clear], atol=ATOL)
    np.testing.assert_array_equal(w_packed[~valid], 0.0)
    assert np.sum(trans[present] < m) > 3  # the threshold is actually exercised
    assert np.sum(w_packed[valid] > 0) < np.sum(w_dense[present] > 0)


def test_packed_weights_stay_exact_after_many_opaque_rays():
    # 1024 rays, each with total optical depth 20 (an opaque surface and samples behind it),
    # followed by one semi-transparent ray: its weights depend only on its own samples.
    n_opaque, n = 1024, 16
    rng = np.random.default_rng(5)
    sigma = np.concatenate([np.full((n_opaque, n), 20.0 / (n * 0.05)), rng.uniform(0, 2, (1, n))]).astype(np.float32)
    delta = np.full_like(sigma, 0.05)
    r = n_opaque + 1
    w_dense = np.asarray(compositing_weights(jnp.asarray(sigma), jnp.asarray(delta)))
    w_packed = np.asarray(packed_compositing_weights(
        jnp.asarray(sigma.ravel()), jnp.asarray(delta.ravel()), jnp.asarray(np.repeat(np.arange(r), n)),
        jnp.ones(r * n, bool))).reshape(r, n)
    np.testing.assert_allclose(w_packed[-1], w_dense[-1], atol=ATOL)


# --- model (coarse + fine) and chunked image rendering ---------------------------------------

import dataclasses  # noqa: E402

from reference import image_rays  # noqa: E402

from nerfkit.core.presets import preset  # noqa: E402
from nerfkit.models.nerf import NeRFModel  # noqa: E402
from nerfkit.models.registry import build_model  # noqa: E402
from nerfkit.rays.cameras import look_at  # noqa: E402
from nerfkit.render.chunked import Renderer  # noqa: E402
from nerfkit.sampling.intervals import midpoints, sample_pdf, stratified_samples  # noqa: E402

N_COARSE, N_FINE = 16, 8


def tiny_config(n_importance):
    cfg = preset("tiny")
    cfg.sampler = dataclasses.replace(cfg.sampler, n_samples=N_COARSE, n_importance=n_importance)
    return cfg


def constant_field(params, sigma, colour_logit):
    """Params of an MLPField whose sigma and rgb are constants (zero output weights)."""
    out = dict(params)
    out["sigma"] = {"w": jnp.zeros_like(params["sigma"]["w"]), "b": jnp.full_like(params["sigma"]["b"], sigma)}
    out["rgb"] = {"w": jnp.zeros_like(params["rgb"]["w"]), "b": jnp.asarray(colour_logit, jnp.float32)}
    return out


def camera_rays(h=3, w=4):
    c2w = look_at(np.array([0.5, -3.5, 1.5]), np.zeros(3))
    o, d = image_rays(c2w, h, w, 3.0)
    return jnp.asarray(o.reshape(-1, 3)), jnp.asarray(d.reshape(-1, 3))


@pytest.fixture(scope="module")
def hierarchical():
    cfg = tiny_config(N_FINE)
    model = build_model(cfg)
    assert isinstance(model, NeRFModel) and model.fine is not None
    params, aux = jax.jit(model.init)(jax.random.PRNGKey(0))
    params = {k: {**p, "sigma": {**p["sigma"], "b": jnp.full_like(p["sigma"]["b"], 0.5)}} for k, p in params.items()}
    render_fn = jax.jit(model.render_rays, static_argnums=(5,))
    return cfg, model, params, aux, render_fn


def test_hierarchical_render_returns_coarse_and_fine_outputs(hierarchical):
    cfg, model, params, aux, render_fn = hierarchical
    o, d = camera_rays()
    r = o.shape[0]
    out = render_fn(params, aux, o, d, jax.random.PRNGKey(1), False)
    assert set(out) >= {"rgb", "depth", "opacity", "depth_normalized", "weights", "coarse"}
    assert out["rgb"].shape == (r, 3) and out["depth"].shape == out["opacity"].shape == (r,)
    assert out["weights"].shape == (r, N_COARSE + N_FINE)
    coarse = out["coarse"]
    assert coarse["rgb"].shape == (r, 3) and coarse["weights"].shape == (r, N_COARSE)
    assert "coarse" not in coarse
    assert float(jnp.min(coarse["opacity"])) > 0.05  # the density bias makes rays non-trivial
    # The fine pass is the fine field rendered at the coarse + importance samples.
    s = cfg.sampler

    @jax.jit
    def reference(params, o, d, coarse_weights):
        viewdir = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
        t = stratified_samples(None, r, s.n_samples, s.near, s.far, perturb=False)
        t_fine = sample_pdf(None, midpoints(t), coarse_weights[:, 1:-1], s.n_importance, deterministic=True)
        t_all = jnp.sort(jnp.concatenate([t, t_fine], -1), -1)
        x = o[:, None] + t_all[..., None] * d[:, None]
        rgb, sigma = model.fine(params["fine"], x, viewdir[:, None])
        return render.volume_render(sigma, rgb, t_all, jnp.linalg.norm(d, axis=-1),
                                    (s.far - s.near) / (s.n_samples + s.n_importance), model.background)

    ref = reference(params, o, d, coarse["weights"])
    for k in ("rgb", "depth", "opacity"):
        np.testing.assert_allclose(np.asarray(out[k]), np.asarray(ref[k]), atol=1e-5, rtol=1e-5, err_msg=k)
    # Evaluation is deterministic: the key does not matter.
    out2 = render_fn(params, aux, o, d, jax.random.PRNGKey(7), False)
    np.testing.assert_array_equal(np.asarray(out2["rgb"]), np.asarray(out["rgb"]))
    # Training jitters samples: different keys, different renders.
    a = render_fn(params, aux, o, d, jax.random.PRNGKey(1), True)
    b = render_fn(params, aux, o, d, jax.random.PRNGKey(2), True)
    assert np.abs(np.asarray(a["rgb"]) - np.asarray(b["rgb"])).max() > 1e-6
    # The loss adds the coarse MSE to the fine one.
    target = jnp.full((r, 3), 0.3)
    loss, logs = model.losses(out, target)
    mse_f = np.mean((np.asarray(out["rgb"]) - 0.3) ** 2)
    mse_c = np.mean((np.asarray(coarse["rgb"]) - 0.3) ** 2)
    np.testing.assert_allclose(float(logs["mse"]), mse_f, rtol=1e-5)
    np.testing.assert_allclose(float(loss), mse_f + mse_c, rtol=1e-5)


def test_constant_density_model_renders_closed_form_opacity():
    # sigma = s everywhere, colour c: with midpoint samples the intervals sum to
    # (far - near - w) + w = far - near (last interval = bin width w), so
    # opacity = 1 - exp(-s |d| (far - near)) and rgb = opacity c + (1 - opacity) bg.
    # With the fine pass: the importance samples lie inside [near + w, far - w], so the
    # merged samples still span [near + w/2, far - w/2] and the last interval is
    # w_f = (far - near) / (N + N_f): the intervals sum to far - near - w + w_f.
    s_val, c_logit = 0.15, np.array([0.5, -1.0, 2.0], np.float32)
    colour = 1 / (1 + np.exp(-c_logit.astype(np.float64)))
    o, d = camera_rays()
    dn = np.linalg.norm(np.asarray(d, np.float64), axis=-1)
    for n_imp in (0, N_FINE):
        cfg = tiny_config(n_imp)
        model = NeRFModel(cfg)
        params, aux = jax.jit(model.init)(jax.random.PRNGKey(3))
        params = {k: constant_field(p, s_val, c_logit) for k, p in params.items()}
        out = jax.jit(model.render_rays, static_argnums=(5,))(params, aux, o, d, jax.random.PRNGKey(0), False)
        near, far, w = cfg.sampler.near, cfg.sampler.far, (cfg.sampler.far - cfg.sampler.near) / N_COARSE
        span = far - near if n_imp == 0 else far - near - w + (far - near) / (N_COARSE + n_imp)
        opacity = 1 - np.exp(-s_val * dn * span)
        np.testing.assert_allclose(np.asarray(out["opacity"]), opacity, atol=1e-5)
        bg = 1.0  # tiny preset: white background
        np.testing.assert_allclose(np.asarray(out["rgb"]), opacity[:, None] * colour + (1 - opacity[:, None]) * bg, atol=1e-5)
        assert ("coarse" in out) == (n_imp > 0)
        if n_imp == 0:
            # depth = sum_i T_i alpha t_i with t_i = near + (i + 1/2) w, alpha = 1 - e^{-s|d|w}.
            tau = s_val * dn[:, None] * w
            i = np.arange(N_COARSE)
            wts = np.exp(-tau * i) * (1 - np.exp(-tau))
            np.testing.assert_allclose(np.asarray(out["depth"]), (wts * (near + (i + 0.5) * w)).sum(-1), atol=5e-5)


def _renderer_case(hierarchical, chunk, h=7, w=9):
    cfg, model, params, aux, _ = hierarchical
    c2w = look_at(np.array([3.0, -2.0, 1.5]), np.zeros(3))
    return Renderer(model, chunk=chunk).render_image(params, aux, c2w, h, w, 6.0)


@pytest.fixture(scope="module")
def full_image(hierarchical):
    return _renderer_case(hierarchical, chunk=64)  # 63 rays in one chunk


def test_renderer_output_shapes_and_matches_direct_render(hierarchical, full_image):
    cfg, model, params, aux, render_fn = hierarchical
    h, w = 7, 9
    assert full_image["rgb"].shape == (h, w, 3)
    for k in ("depth", "depth_normalized", "opacity"):
        assert full_image[k].shape == (h, w)
    c2w = look_at(np.array([3.0, -2.0, 1.5]), np.zeros(3))
    o, d = image_rays(c2w, h, w, 6.0)
    direct = render_fn(params, aux, jnp.asarray(o.reshape(-1, 3)), jnp.asarray(d.reshape(-1, 3)), jax.random.PRNGKey(0), False)
    np.testing.assert_allclose(full_image["rgb"].reshape(-1, 3), np.asarray(direct["rgb"]), atol=1e-5)
    np.testing.assert_allclose(full_image["opacity"].ravel(), np.asarray(direct["opacity"]), atol=1e-5)
    assert np.ptp(full_image["depth"]) > 1e-3  # pixels differ: a meaningful comparison


@pytest.mark.parametrize("chunk", [16, 21])  # 63 = 3 * 21; 63 is not a multiple of 16 (padded last chunk)
def test_chunked_render_equals_single_chunk(hierarchical, full_image, chunk):
    chunked = _renderer_case(hierarchical, chunk=chunk)
    for k, v in full_image.items():
        assert chunked[k].shape == v.shape
        np.testing.assert_allclose(chunked[k], v, atol=1e-5, rtol=1e-5, err_msg=k)
