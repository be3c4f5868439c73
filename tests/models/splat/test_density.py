"""Density control: MCMC relocation / growth / noise (mcmc.py) and classic clone-split-prune (densify.py)."""

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import densify, mcmc
from nerfkit.models.splat.gaussians import init_random
from nerfkit.models.splat.optim import (
    LearningRates,
    init_state,
    make_optimizers,
    reset_rows,
)


def scene(n=200, n_dead=40, seed=0):
    rng = np.random.default_rng(seed)
    p = init_random(n, seed=seed)
    p["opacity"] = rng.normal(0.0, 1.0, n).astype(np.float32)
    p["sh_rest"] = rng.normal(size=p["sh_rest"].shape).astype(np.float32)
    dead = rng.choice(n, n_dead, replace=False)
    p["opacity"][dead] = -8.0  # sigmoid = 3.4e-4 < 0.005
    return p, np.sort(dead)


def sigmoid(x):
    return 1 / (1 + np.exp(-np.asarray(x, np.float64)))


def test_relocation_update_preserves_opacity():
    o = np.array([0.3, 0.9, 0.5, 0.05])
    n = np.array([1, 2, 5, 50])
    o_new, factor = mcmc.relocation_update(o, n)
    np.testing.assert_allclose(1 - (1 - o_new) ** n, o, rtol=1e-12)  # n copies composite to the old opacity
    np.testing.assert_allclose([o_new[0], factor[0]], [o[0], 1.0], rtol=1e-14)  # n = 1: unchanged
    assert np.all(np.isfinite(factor)) and np.all(factor > 0)
    # n = 2 by hand: denom = o_new + (o_new - o_new^2 / sqrt 2)
    on = o_new[1]
    np.testing.assert_allclose(factor[1], 0.9 / (2 * on - on**2 / np.sqrt(2)), rtol=1e-12)


def test_relocation_keeps_count_and_moves_only_dead():
    p, dead = scene()
    n = len(p["means"])
    active = np.ones(n, bool)
    new, touched = mcmc.relocate(p, active, np.random.default_rng(1))
    assert {k: v.shape for k, v in new.items()} == {k: v.shape for k, v in p.items()}
    alive = np.setdiff1d(np.arange(n), dead)
    sources = np.setdiff1d(touched, dead)
    assert np.all(np.isin(dead, touched)) and np.all(np.isin(sources, alive)) and len(sources) > 0
    untouched = np.setdiff1d(np.arange(n), touched)
    for k in p:  # Gaussians neither dead nor sampled are bit-for-bit unchanged
        np.testing.assert_array_equal(new[k][untouched], p[k][untouched])
    for k in ("means", "quats", "sh_dc", "sh_rest"):  # sources keep position, rotation, colour
        np.testing.assert_array_equal(new[k][sources], p[k][sources])
    # every dead slot now copies a live source exactly (position, rotation, colour), with its new opacity/scale
    for d in dead:
        (src,) = np.flatnonzero(np.all(p["means"][sources] == new["means"][d], axis=1))
        s = sources[src]
        np.testing.assert_array_equal(new["sh_rest"][d], p["sh_rest"][s])
        assert new["opacity"][d] == new["opacity"][s] and np.all(new["log_scales"][d] == new["log_scales"][s])
    assert np.all(sigmoid(new["opacity"]) > mcmc.DEAD_OPACITY)
    # a source split into n copies has opacity 1 - (1 - o)^(1/n) (clamped at the dead threshold)
    copies = np.array([np.sum(np.all(new["means"][dead] == p["means"][s], axis=1)) for s in sources]) + 1
    expect = np.maximum(1 - (1 - sigmoid(p["opacity"][sources])) ** (1 / copies), mcmc.DEAD_OPACITY)
    np.testing.assert_allclose(sigmoid(new["opacity"][sources]), expect, rtol=1e-5)


def test_relocation_ignores_inactive_and_nothing_dead():
    p, dead = scene()
    active = np.ones(len(p["means"]), bool)
    active[dead] = False  # dead but not in use: not relocated
    new, touched = mcmc.relocate(p, active, np.random.default_rng(0))
    assert len(touched) == 0 and new is p


def test_grow_activates_copies():
    p, _ = scene(n_dead=0)
    active = np.zeros(200, bool)
    active[:100] = True
    new, act, touched = mcmc.grow(p, active, np.random.default_rng(0), rate=0.1)
    assert act.sum() == 110 and np.all(act[:110])
    assert np.all(np.isin(np.arange(100, 110), touched))
    for d in range(100, 110):  # each new slot sits on an active Gaussian
        assert np.any(np.all(new["means"][:100] == new["means"][d], axis=1))


def test_noise_moves_only_transparent_gaussians():
    p, dead = scene()
    params = {k: jnp.asarray(v) for k, v in p.items()}
    noise = np.asarray(mcmc.position_noise(jax.random.PRNGKey(0), params, 1e-3))
    opaque = sigmoid(p["opacity"]) > 0.2
    assert np.abs(noise[opaque]).max() < 1e-6
    assert np.abs(noise[dead]).mean() > 1e-3
    g = np.asarray(mcmc.noise_gate(jnp.array([0.0, 0.005, 0.1])))
    assert g[0] > 0.6 and abs(g[1] - 0.5) < 1e-6 and g[2] < 1e-4


def test_reset_rows_zeroes_adam_moments():
    p, _ = scene(n=10, n_dead=0)
    params = {k: jnp.asarray(v) for k, v in p.items()}
    opts = make_optimizers(LearningRates(), 4.0)
    state = init_state(opts, params)
    state = jax.tree_util.tree_map(lambda x: x + 1 if x.ndim else x, state)
    state = reset_rows(state, np.array([2, 5]), 10)
    mu = state["sh_rest"].inner_state[0].mu
    assert np.all(np.asarray(mu)[[2, 5]] == 0) and np.all(np.asarray(mu)[[0, 1, 3]] == 1)


def test_classic_clone_split_prune():
    n = 20
    p = init_random(n, seed=0)
    p["opacity"][:] = 0.0
    p["log_scales"][:10] = np.log(0.001)  # small: clone
    p["log_scales"][10:] = np.log(0.2)  # large: split
    p["opacity"][7] = -8.0  # pruned
    active = np.zeros(n, bool)
    active[:16] = True
    grads = np.zeros(n, np.float32)
    grads[[0, 1, 12]] = 1e-3  # above the 2e-4 threshold
    stats = {"grad_sum": grads, "count": np.ones(n, np.float32), "max_radius": np.ones(n, np.float32)}
    sched = densify.ClassicSchedule()
    new, act, touched = densify.densify(p, active, stats, 4.0, np.random.default_rng(0), sched, 100, False)
    assert act.sum() == 16 + 3 - 1  # 2 clones, 1 split (one new slot), 1 pruned
    assert not act[7] and np.all(act[16:19])
    np.testing.assert_array_equal(new["means"][16], p["means"][0])  # clones: exact copies in free slots
    np.testing.assert_array_equal(new["means"][17], p["means"][1])
    np.testing.assert_allclose(np.exp(new["log_scales"][[12, 18]]), 0.2 / 1.6, rtol=1e-5)  # split: both shrunk
    assert not np.allclose(new["means"][12], p["means"][12])  # ... and resampled within the parent
    assert np.linalg.norm(new["means"][18] - p["means"][12]) < 5 * 0.2
    assert set(touched) == {0, 1, 16, 17, 12, 18}
    reset = densify.reset_opacity(new, 0.01)
    assert sigmoid(reset["opacity"]).max() <= 0.01 + 1e-6
