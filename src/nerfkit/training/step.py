"""One training step, jit-compiled: the optimiser, the batch of rays drawn from the training images,
and step(state, step, images, poses) -> (state, metrics) for ray models (image models make their own,
models/base.py). The loop that runs it and writes the run folder is trainer.py.
"""

from __future__ import annotations

import copy
import functools

import jax
import jax.numpy as jnp
import optax

from nerfkit.core.config import Config
from nerfkit.data.capture import SceneData
from nerfkit.rays.cameras import (
    draw_pixels,
    ray_table,
    rotate_directions,
    table_directions,
)
from nerfkit.training import parallel


def make_optimizer(cfg: Config, model=None):
    """Adam with lr(step) = lr * decay_rate ** (step / decay_steps), continuous decay; a model with its own
    optimiser (Gaussian splats) gives (optimiser, schedule) itself."""
    if model is not None and model.supports.renders_images:
        return model.make_optimizer(cfg)
    t = cfg.train
    schedule = optax.exponential_decay(t.lr, transition_steps=t.lr_decay_steps, decay_rate=t.lr_decay_rate)
    return optax.adam(schedule, b2=t.adam_b2, eps=t.adam_eps), schedule


def draw_batch(key, step, n_images: int, h: int, w: int, t, sizes=None, batch: int | None = None):
    """The pixels (img, i, j) [batch] (default: batch_rays) of one step, uniform over n_images images of h x w pixels;
    inside the centred crop of side precrop_frac while step < precrop_steps (t: the TrainConfig). On
    images of several sizes (sizes [N, 2] of (height, width), multiscale data) every pixel of every
    image is equally likely (cameras.draw_pixels) and there is no crop."""
    b = t.batch_rays if batch is None else batch
    k_img, k_i, k_j = jax.random.split(key, 3)
    if sizes is not None:
        return draw_pixels(k_img, b, sizes)
    crop_h = max(1, int(round(h * t.precrop_frac)))
    crop_w = max(1, int(round(w * t.precrop_frac)))
    img = jax.random.randint(k_img, (b,), 0, n_images)
    cropping = step < t.precrop_steps
    hh = jnp.where(cropping, crop_h, h)
    ww = jnp.where(cropping, crop_w, w)
    i = (h - hh) // 2 + jnp.floor(jax.random.uniform(k_i, (b,)) * hh).astype(jnp.int32)
    j = (w - ww) // 2 + jnp.floor(jax.random.uniform(k_j, (b,)) * ww).astype(jnp.int32)
    return img, i, j


def make_train_step(model, optimizer, data: SceneData, cfg: Config, mesh=None):
    """A jitted step(state, step, images, poses) -> (state, metrics).

    With a device mesh (parallel.data_mesh), the drawn rays (or, for models that pack samples, the
    packed samples: model.supports.parallel) are split over its devices, and state, images and poses must be
    replicated on it (parallel.replicate); the step computes the same.

    Each step draws model.rays_per_step pixels (--batch-rays, or fewer where the model's sample budget says
    so) uniformly over all training images (inside the centre crop while step < precrop_steps; on multiscale data every pixel of every level is
    equally likely and its loss is weighted by its area, SceneData.lossmult), makes their rays
    with each frame's camera (cameras.ray_table: pinhole intrinsics, or per-pixel lens tables),
    renders them (with the appearance embedding of their image, where the model has them, and as cones
    of their frame's pixel radius for the anti-aliased models) and
    applies one Adam update. The randomness of step s is fold_in(PRNGKey(seed), s), so a resumed run
    repeats exactly. A step whose loss or gradients are not finite is not applied.

    A model with its own step (Gaussian splats, splat/method.py: one view per step) makes it instead.
    """
    if model.supports.renders_images:
        return model.make_train_step(optimizer, data, cfg, mesh)
    t = cfg.train
    h, w = data.height, data.width
    table = parallel.replicate({k: jnp.asarray(v) for k, v in ray_table(data.cameras).items()}, mesh)
    split_rays = mesh is not None and model.supports.parallel == "rays"
    if mesh is not None and not split_rays:  # the model splits its packed samples (supports.parallel "samples")
        parallel.check_batch(cfg.sampler.max_samples, mesh, "--max-samples")
        model = copy.copy(model)
        model.shard_samples = functools.partial(parallel.shard_rays, mesh=mesh)
    base_key = jax.random.PRNGKey(t.seed)
    sizes = None if data.sizes is None else jnp.asarray(data.sizes)
    lossmult = jnp.asarray(data.lossmult)

    def step_fn(state, step, images, poses, table):
        key = jax.random.fold_in(base_key, step)
        k_draw, k_render, k_aux = jax.random.split(key, 3)
        img, i, j = draw_batch(k_draw, step, images.shape[0], h, w, t, sizes, model.rays_per_step)
        if split_rays:
            img, i, j = parallel.shard_rays((img, i, j), mesh)
        weights = None if sizes is None else lossmult[img]
        o, d = rotate_directions(poses[img], table_directions(table, img, i, j))
        params = state["params"]
        aux = model.update_aux(params, state["aux"], step, k_aux)
        loss_fn = ray_loss(model, aux, o, d, k_render, img, table["radius"][img], images[img, i, j], weights)
        (loss, (parts, out)), grads = jax.value_and_grad(loss_fn, has_aux=True)(params)
        new_state, finite = apply_if_finite(optimizer, state, grads, loss, aux)
        metrics = {"loss": loss, "mse": parts["mse"], "finite": finite}
        if model.supports.step_metrics:
            metrics.update(model.step_metrics(out))
        return new_state, metrics

    jitted = jax.jit(step_fn, donate_argnums=(0,))
    return lambda state, step, images, poses: jitted(state, step, images, poses, table)


def ray_loss(model, aux, o, d, key, image_idx, radii, target, weights=None):
    """loss_fn(params) -> (loss, (parts, out)): the model's losses (model.losses, per-ray weights [R] when
    given) of rendering rays o, d [R, 3] of images image_idx [R] (cones of radii [R]) against target [R, 3]."""

    def loss_fn(p):
        out = model.render_rays(p, aux, o, d, key, train=True, image_idx=image_idx, radii=radii)
        loss, parts = model.losses(out, target) if weights is None else model.losses(out, target, weights)
        return loss, (parts, out)

    return loss_fn


def apply_if_finite(optimizer, state, grads, loss, aux):
    """(new state, finite): state with one optimiser update of its params by grads and the step's aux, where
    the loss and every gradient are finite (finite: True); otherwise its params and optimiser state unchanged."""
    params = state["params"]
    updates, opt_state = optimizer.update(grads, state["opt_state"], params)
    new_params = optax.apply_updates(params, updates)
    finite = jnp.isfinite(loss)
    for g in jax.tree_util.tree_leaves(grads):
        finite = finite & jnp.all(jnp.isfinite(g))
    keep = lambda new, old: jnp.where(finite, new, old)  # noqa: E731
    new_state = {
        "params": jax.tree_util.tree_map(keep, new_params, params),
        "opt_state": jax.tree_util.tree_map(keep, opt_state, state["opt_state"]),
        "aux": aux,
    }
    return new_state, finite


def init_state(model, optimizer, seed: int):
    params, aux = model.init(jax.random.PRNGKey(seed))
    return {"params": params, "opt_state": optimizer.init(params), "aux": aux}


