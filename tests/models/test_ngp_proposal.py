"""The hash-grid field with proposal sampling (nerfkit.models.ngp_proposal): picked for unbounded scenes, a fixed
number of samples per ray so a step holds thousands of rays, and runs written before it still load as the
marching model they trained."""

import json

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.config import Config
from nerfkit.core.presets import preset
from nerfkit.models.ngp import NGPModel
from nerfkit.models.ngp_proposal import ProposalNGPModel
from nerfkit.models.registry import build_model
from nerfkit.rays.cameras import look_at
from nerfkit.render.chunked import Renderer
from nerfkit.render.images import make_renderer
from nerfkit.sampling.proposal import interlevel_loss
from nerfkit.training.step import init_state, make_optimizer, ray_loss


def _unbounded(**sampler):
    cfg = preset("ngp")
    cfg.field.scene_type, cfg.field.bound = "unbounded", 1.5
    cfg.field.hash_levels, cfg.field.hash_log2_size, cfg.field.hash_max_res = 4, 12, 64
    cfg.sampler.near, cfg.sampler.far, cfg.sampler.occ_res = 0.05, 1e3, 16
    for k, v in sampler.items():
        setattr(cfg.sampler, k, v)
    return cfg


def test_the_sampler_is_picked_by_scene_and_setting():
    assert type(build_model(_unbounded())) is ProposalNGPModel
    assert type(build_model(_unbounded(sampling="occupancy"))) is NGPModel
    bounded = preset("ngp")
    assert type(build_model(bounded)) is NGPModel
    bounded.sampler.sampling = "proposal"
    assert type(build_model(bounded)) is ProposalNGPModel
    assert ProposalNGPModel.supports.family == "rays" and ProposalNGPModel.supports.parallel == "rays"
    assert isinstance(make_renderer(build_model(_unbounded())), Renderer)


def test_runs_written_before_proposal_sampling_load_as_the_marching_model():
    old = json.loads(Config().to_json())
    old["field"]["kind"], old["field"]["scene_type"] = "ngp", "unbounded"
    del old["sampler"]["sampling"]
    assert Config.from_dict(old).sampler.sampling == "occupancy"
    assert type(build_model(Config.from_dict(old))) is NGPModel


def test_a_step_holds_the_sample_budget_in_rays():
    m = build_model(_unbounded())
    assert m.rays_per_step == 2048 == 65536 // m.cfg.sampler.field_samples  # the ngp preset's budget
    assert build_model(_unbounded(field_samples=16)).rays_per_step == 4096  # at most --batch-rays
    assert "proposal sampling: 64 + 32 proposal and 32 field samples per ray, 2048 rays per step" in \
        NGPModel.describe(m.cfg)


def _rays(n=64):
    c2w = look_at(np.array([0.0, -1.2, 0.3]), np.zeros(3))
    rng = np.random.default_rng(0)
    d = np.concatenate([rng.uniform(-0.4, 0.4, (n, 2)), -np.ones((n, 1))], 1) @ c2w[:3, :3].T
    return jnp.broadcast_to(jnp.asarray(c2w[:3, 3]), (n, 3)), jnp.asarray(d, jnp.float32)


def test_rendering_is_deterministic_and_every_ray_is_complete():
    m = build_model(_unbounded())
    params, aux = m.init(jax.random.PRNGKey(0))
    o, d = _rays()
    a = m.render_rays(params, aux, o, d, jax.random.PRNGKey(1), train=False)
    b = m.render_rays(params, aux, o, d, jax.random.PRNGKey(2), train=False)
    assert np.array_equal(np.asarray(a["rgb"]), np.asarray(b["rgb"])) and bool(jnp.all(a["complete"]))
    # A young field: every density starts at INIT_OPTICAL_DEPTH over the inner ball, so rays are not spent
    # in front of the camera (their weight spreads into the scene and beyond).
    assert float(jnp.min(a["depth_median"])) > 0.5


def test_the_proposals_learn_to_put_the_samples_where_the_field_weight_is():
    """The field's weight all at s* = 0.9 (an opaque wall at distance g^-1(0.9)): Adam on the interlevel loss
    alone moves the proposals until most of the field's samples land next to the wall, where at first
    they were spread evenly in s."""
    import optax

    cfg = _unbounded()
    m = build_model(cfg)
    params, aux = m.init(jax.random.PRNGKey(0))
    o, d = _rays()
    wall = 0.9

    def near_wall(p, key):
        edges, _ = m.sample(p, o, d, key, train=False)
        return float(jnp.mean(jnp.abs(0.5 * (edges[:, 1:] + edges[:, :-1]) - wall) < 0.05))

    def loss(prop, key):
        p = dict(params, proposal=prop)
        edges, rounds = m.sample(p, o, d, key, train=True)
        w = ((edges[:, :-1] <= wall) & (edges[:, 1:] > wall)).astype(jnp.float32)  # the field's histogram
        return interlevel_loss(edges, w, [e for e, _ in rounds], [w for _, w in rounds])

    opt = optax.adam(1e-2)
    prop, state = params["proposal"], opt.init(params["proposal"])
    before = near_wall(params, jax.random.PRNGKey(1))
    grad = jax.jit(jax.value_and_grad(loss))
    first = None
    for k in range(150):
        value, g = grad(prop, jax.random.PRNGKey(k))
        first = float(value) if first is None else first
        upd, state = opt.update(g, state)
        prop = optax.apply_updates(prop, upd)
    after = near_wall(dict(params, proposal=prop), jax.random.PRNGKey(1))
    assert before < 0.1 and after > 0.5, (before, after)
    assert float(value) < 0.2 * first, (first, float(value))


def test_training_fits_a_colour():
    """A few Adam steps of the whole loss (MSE + interlevel + distortion) on rays of one colour: the MSE falls
    and every term stays finite."""
    cfg = _unbounded(max_samples=64 * 32)
    cfg.train.lr = 1e-2
    m = build_model(cfg)
    opt, _ = make_optimizer(cfg, m)
    state = init_state(m, opt, 0)
    o, d = _rays()
    target = jnp.broadcast_to(jnp.asarray([0.9, 0.2, 0.1]), (64, 3))
    first = last = None

    @jax.jit
    def step(state, k):
        aux = m.update_aux(state["params"], state["aux"], k, jax.random.PRNGKey(7))
        (loss, (parts, _)), g = jax.value_and_grad(ray_loss(m, aux, lambda p: (o, d), jax.random.fold_in(jax.random.PRNGKey(0), k),
                                                            None, None, target), has_aux=True)(state["params"])
        upd, opt_state = opt.update(g, state["opt_state"], state["params"])
        params = jax.tree_util.tree_map(lambda p, u: p + u, state["params"], upd)
        return {"params": params, "opt_state": opt_state, "aux": aux}, parts

    for k in range(60):
        state, parts = step(state, k)
        first = first or {n: float(v) for n, v in parts.items()}
        last = {n: float(v) for n, v in parts.items()}
    assert last["mse"] < 0.1 * first["mse"], (first, last)
    assert np.isfinite(list(last.values())).all() and last["distortion"] >= 0 and last["interlevel"] >= 0
