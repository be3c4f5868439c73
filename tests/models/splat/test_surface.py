"""Normal consistency (models/splat/surface.py): zero for flat Gaussians tangent to the plane they tile, the
2DGS value 1 - cos(tilt) for tilted ones, and a gradient that turns them back; the depth map's normals exact
on a plane. Depth distortion: the pairwise sum over the blend weights, zero on one plane, a gradient that draws
two layers together, nothing at a depth edge."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.data.procedural.scene import look_at
from nerfkit.models.splat.gaussians import all_sh, splat_inputs
from nerfkit.models.splat import surface
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.surface import (EDGE_SPREAD, SURFACE_CHANNELS, depth_distortion, depth_normals,
                                          normal_consistency, pixel_directions, surface_channels,
                                          with_surface_channels)

SIZE, FOCAL, SLOPE = 64, 60.0, 0.2  # the plane z = SLOPE x, seen from (0, 0, 3) looking down -z
C2W = np.eye(4, dtype=np.float32)
C2W[2, 3] = 3.0
INTR = (FOCAL, FOCAL, SIZE / 2, SIZE / 2)


def tiled_plane(tilt: float) -> dict:
    """13 x 13 flat, opaque Gaussians on the plane, each turned `tilt` radians about y away from it."""
    xs = np.linspace(-0.6, 0.6, 13)
    x, y = (a.ravel() for a in np.meshgrid(xs, xs))
    n = len(x)
    angle = np.arctan(SLOPE) + tilt
    quat = np.tile([np.cos(-angle / 2), 0.0, np.sin(-angle / 2), 0.0], (n, 1))
    return {"means": jnp.asarray(np.stack([x, y, SLOPE * x], -1), jnp.float32),
            "log_scales": jnp.log(jnp.tile(jnp.array([0.1, 0.1, 0.002]), (n, 1))),
            "quats": jnp.asarray(quat, jnp.float32), "opacity": jnp.full((n,), 4.0),
            "sh_dc": jnp.zeros((n, 1, 3)), "sh_rest": jnp.zeros((n, 15, 3))}


def loss_of(params: dict) -> jax.Array:
    proj, colors, opac = splat_inputs(params, jnp.asarray(C2W), INTR, SIZE, SIZE, all_sh(params))
    channels = jnp.concatenate([colors, surface_channels(params["means"], params["log_scales"], params["quats"],
                                                         jnp.asarray(C2W))], axis=-1)
    image, alpha = rasterize(proj["means2d"], proj["conics"], channels, opac, proj["depths"], proj["radii"],
                             jnp.zeros(3 + SURFACE_CHANNELS), SIZE, SIZE, backend="numba")
    assert float(jnp.mean(alpha > 0.5)) > 0.15  # the plane fills a good part of the view
    return normal_consistency(image[..., 3:], alpha, jnp.asarray(INTR))


def test_tangent_gaussians_cost_nothing_and_tilted_ones_cost_one_minus_the_cosine():
    assert abs(float(loss_of(tiled_plane(0.0)))) < 1e-5
    for tilt in (0.15, 0.3):
        got = float(loss_of(tiled_plane(tilt)))
        assert 0.6 * (1 - np.cos(tilt)) < got < 1.1 * (1 - np.cos(tilt)), (tilt, got)


def test_a_gradient_step_turns_tilted_gaussians_back_towards_the_plane():
    p = tiled_plane(0.3)
    loss, grads = jax.value_and_grad(loss_of)(p)
    assert all(bool(jnp.isfinite(g).all()) for g in grads.values())
    step = dict(p, quats=p["quats"] - 0.5 * grads["quats"] / jnp.linalg.norm(grads["quats"]))
    assert float(loss_of(step)) < 0.8 * float(loss)


def test_depth_normals_of_a_plane_are_its_normal():
    rays = pixel_directions(jnp.asarray(INTR), SIZE, SIZE)
    normal = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])  # facing the camera (OpenCV axes)
    depth = -2.5 / jnp.sum(rays * jnp.asarray(normal, jnp.float32), -1)  # the plane n . x = -2.5
    got = np.asarray(depth_normals(depth, rays))
    assert got.shape == (SIZE - 2, SIZE - 2, 3)
    np.testing.assert_allclose(got.reshape(-1, 3), np.broadcast_to(normal, ((SIZE - 2) ** 2, 3)), atol=1e-4)


def two_layers(gap: float, n: int = 5) -> dict:
    """n x n half-opaque flat Gaussians on the plane z = SLOPE x and as many `gap` nearer the camera (+z)."""
    xs = np.linspace(-0.6, 0.6, n)
    x, y = (a.ravel() for a in np.meshgrid(xs, xs))
    angle = np.arctan(SLOPE)
    means = np.concatenate([np.stack([x, y, SLOPE * x], -1), np.stack([x, y, SLOPE * x + gap], -1)])
    k = len(means)
    return {"means": jnp.asarray(means, jnp.float32),
            "log_scales": jnp.log(jnp.tile(jnp.array([0.25, 0.25, 0.002]), (k, 1))),
            "quats": jnp.asarray(np.tile([np.cos(-angle / 2), 0.0, np.sin(-angle / 2), 0.0], (k, 1)), jnp.float32),
            "opacity": jnp.zeros((k,)), "sh_dc": jnp.zeros((k, 1, 3)), "sh_rest": jnp.zeros((k, 15, 3))}


OBLIQUE = jnp.asarray(look_at((0.5, 0.7, 3.0)), jnp.float32)  # so that q_k has x, y and z parts


def render_surface(params: dict, extra: jax.Array | None = None):
    """(channels after the colour [H, W, 12 (+ K)], alpha [H, W]) of params seen from OBLIQUE with the surface
    and distortion channels (and `extra` [N, K] after them)."""
    proj, colors, opac = splat_inputs(params, OBLIQUE, INTR, SIZE, SIZE, all_sh(params))
    channels, bg = with_surface_channels(colors, jnp.zeros(3), params, OBLIQUE, distortion=True)
    if extra is not None:
        channels, bg = jnp.concatenate([channels, extra], -1), jnp.zeros(channels.shape[-1] + extra.shape[-1])
    image, alpha = rasterize(proj["means2d"], proj["conics"], channels, opac, proj["depths"], proj["radii"], bg,
                             SIZE, SIZE, backend="numba")
    return image[..., 3:], alpha


def distortion_of(params: dict) -> jax.Array:
    channels, alpha = render_surface(params)
    return depth_distortion(channels, alpha, jnp.asarray(INTR))


def test_depth_distortion_is_the_pairwise_sum_over_the_blend_weights():
    """Each Gaussian's blend weight w_k(p) rendered as a one-hot channel, its inverse depth s_k(p) = q_k . r_p on
    its plane: the mean of sum_ij w_i w_j (s_i - s_j)^2 D^2 over the pixels more than half opaque."""
    params = two_layers(0.1)
    k = len(params["means"])
    channels, alpha = render_surface(params, jnp.eye(k))
    w = np.asarray(channels[..., 12:], np.float64)  # [H, W, K]
    q = np.asarray(surface_channels(params["means"], params["log_scales"], params["quats"], OBLIQUE), np.float64)[:, 3:]
    assert np.all(np.abs(q).min(0) > 0.01)
    s = np.asarray(pixel_directions(jnp.asarray(INTR), SIZE, SIZE), np.float64) @ q.T  # [H, W, K]
    pairs = np.einsum("hwi,hwj,hwij->hw", w, w, (s[..., :, None] - s[..., None, :]) ** 2)
    a = np.asarray(alpha, np.float64)
    depth = a / np.maximum(np.sum(w * s, -1), 1e-9)
    ok = a > 0.5
    assert ok.mean() > 0.15 and float(np.median(pairs[ok])) > 0  # the layers overlap over much of the view
    spread = pairs * depth ** 2
    assert spread[ok].max() < EDGE_SPREAD  # 0.1 apart at a depth of 3: no pixel is a depth edge
    got = float(depth_distortion(channels[..., :12], alpha, jnp.asarray(INTR)))
    np.testing.assert_allclose(got, np.mean(spread[ok]), rtol=1e-3)


def test_one_plane_has_no_distortion_and_a_gradient_step_draws_two_layers_together():
    one = two_layers(0.0)
    assert abs(float(distortion_of(one))) < 1e-7
    params = two_layers(0.1)
    loss, grads = jax.value_and_grad(distortion_of)(params)
    assert float(loss) > 1e-4
    half = len(params["means"]) // 2
    dz = np.asarray(grads["means"][:, 2])
    assert np.all(dz[:half] <= 0) and np.all(dz[half:] >= 0) and dz[:half].sum() < 0 < dz[half:].sum()
    step = dict(params, means=params["means"] - 0.02 * grads["means"] / jnp.abs(grads["means"]).max())
    assert float(distortion_of(step)) < float(loss)


def test_a_depth_edge_is_left_to_the_photometric_loss(monkeypatch):
    """Layers 1.5 apart (a silhouette before a wall) spread their depths by far more than EDGE_SPREAD: where both
    are blended the pixels count 0, so L_d is under that of layers 0.1 apart, where without the rule it is over
    fifty times theirs."""
    near, far = two_layers(0.1), two_layers(1.5)
    assert float(distortion_of(far)) < float(distortion_of(near))
    monkeypatch.setattr(surface, "EDGE_SPREAD", np.inf)
    assert float(distortion_of(far)) > 50 * float(distortion_of(near))
