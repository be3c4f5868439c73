"""Normal consistency (models/splat/surface.py): zero for flat Gaussians tangent to the plane they tile, the
2DGS value 1 - cos(tilt) for tilted ones, and a gradient that turns them back; the depth map's normals exact
on a plane."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.gaussians import all_sh, splat_inputs
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.surface import (SURFACE_CHANNELS, depth_normals, normal_consistency, pixel_directions,
                                          surface_channels)

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
