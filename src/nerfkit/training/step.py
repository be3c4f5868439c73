"""One training step, jit-compiled: the optimiser, the batch of rays drawn from the training images,
and step(state, step, images, poses) -> (state, metrics) for ray models (image models make their own,
models/base.py). The loop that runs it and writes the run folder is trainer.py.

Pose refinement (--pose-refine on; rays/correction.py): params["cam_pose"] [N, 6] holds a correction xi_k of
each training photo's pose, c2w_k T(xi_k) (translations in units of correction.camera_extent of the training
poses), learned with the field from the first step by its own Adam at

    lr_pose(s) = POSE_LR decay(s),

decay(s) the field's exponential decay (--lr-decay-rate ** (s / --lr-decay-steps)). No warm-up: a hash grid
fits each photo at its given pose within a few hundred steps and then holds it there (the procedural unbounded
capture, 35 photos 0.96 degrees off, ngp, 1000 steps: a warm-up of 100 steps and a ramp of 100 left the poses
0.96 degrees off and the held-out photos at 12.4 dB; learned from the first step, 0.50 degrees and 21.0 dB).
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
from nerfkit.rays.correction import camera_extent, corrected_pose
from nerfkit.training import parallel

POSE_LR = 5e-4  # nerfstudio's camera optimiser uses 6e-4 (SO3xR3); 3DGS ports 5e-4 to 1e-3


def refines_poses(model) -> bool:
    """Whether a ray model learns a pose correction per training photo (--pose-refine on, where it supports it)."""
    return model.supports.pose_refine and model.cfg.train.pose_refine == "on"


def pose_schedule(cfg: Config):
    """lr_pose(step) (module docstring)."""
    t = cfg.train
    return optax.exponential_decay(POSE_LR, transition_steps=t.lr_decay_steps, decay_rate=t.lr_decay_rate)


def make_optimizer(cfg: Config, model=None):
    """Adam with lr(step) = lr * decay_rate ** (step / decay_steps), continuous decay; a model with its own
    optimiser (Gaussian splats) gives (optimiser, schedule) itself."""
    if model is not None and model.supports.renders_images:
        return model.make_optimizer(cfg)
    t = cfg.train
    schedule = optax.exponential_decay(t.lr, transition_steps=t.lr_decay_steps, decay_rate=t.lr_decay_rate)
    adam = optax.adam(schedule, b2=t.adam_b2, eps=t.adam_eps)
    if model is None or not refines_poses(model):
        return adam, schedule
    labels = lambda params: {k: ("pose" if k == "cam_pose" else "field") for k in params}  # noqa: E731
    return optax.multi_transform({"field": adam, "pose": optax.adam(pose_schedule(cfg), eps=1e-8)}, labels), schedule


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
    extent = camera_extent(data.poses) if refines_poses(model) else None

    def step_fn(state, step, images, poses, table):
        key = jax.random.fold_in(base_key, step)
        k_draw, k_render, k_aux = jax.random.split(key, 3)
        img, i, j = draw_batch(k_draw, step, images.shape[0], h, w, t, sizes, model.rays_per_step)
        if split_rays:
            img, i, j = parallel.shard_rays((img, i, j), mesh)
        weights = None if sizes is None else lossmult[img]
        rays = camera_rays(poses[img], table_directions(table, img, i, j), img, extent)
        params = state["params"]
        aux = model.update_aux(params, state["aux"], step, k_aux)
        loss_fn = ray_loss(model, aux, rays, k_render, img, table["radius"][img], images[img, i, j], weights)
        (loss, (parts, out)), grads = jax.value_and_grad(loss_fn, has_aux=True)(params)
        new_state, finite = apply_if_finite(optimizer, state, grads, loss, aux)
        metrics = {"loss": loss, "mse": parts["mse"], "finite": finite}
        if model.supports.step_metrics:
            metrics.update(model.step_metrics(out))
        return new_state, metrics

    jitted = jax.jit(step_fn, donate_argnums=(0,))
    return lambda state, step, images, poses: jitted(state, step, images, poses, table)


def camera_rays(c2w, d_cam, img, extent: float | None):
    """rays(params) -> (o, d) [R, 3]: the rays of camera-space directions d_cam [R, 3] from poses c2w [R, 4, 4] of
    training photos img [R], corrected by params["cam_pose"][img] (module docstring) where extent is given."""
    if extent is None:
        o, d = rotate_directions(c2w, d_cam)
        return lambda params: (o, d)
    return lambda params: rotate_directions(corrected_pose(c2w, params["cam_pose"][img], extent), d_cam)


def ray_loss(model, aux, rays, key, image_idx, radii, target, weights=None):
    """loss_fn(params) -> (loss, (parts, out)): the model's losses (model.losses, per-ray weights [R] when
    given) of rendering the rays o, d = rays(params) [R, 3] (camera_rays) of images image_idx [R] (cones of radii
    [R]) against target [R, 3]."""

    def loss_fn(p):
        o, d = rays(p)
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
    """{params, opt_state, aux} at the start: the model's, with zero pose corrections where it refines poses."""
    params, aux = model.init(jax.random.PRNGKey(seed))
    if not model.supports.renders_images and refines_poses(model):
        params["cam_pose"] = jnp.zeros((model.cfg.field.appearance_count, 6), jnp.float32)
    return {"params": params, "opt_state": optimizer.init(params), "aux": aux}


