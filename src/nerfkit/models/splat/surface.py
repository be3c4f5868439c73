"""Normal consistency for splats (2DGS, Huang et al. 2024, eq. 14, with 3D Gaussians): a training term that
makes the Gaussians lie flat along the surface their own depth describes, so that the depth the exports fuse
agrees from view to view.

Each Gaussian k gets, in the OpenCV axes of the view (p_c = V (p - o), project.world_to_camera):

    n_k   the axis of its smallest scale (a column of R_k), turned to face the camera (n_k . mu_k < 0)
    q_k   = n_k / delta_k, delta_k = min(n_k . mu_k, -DELTA_MIN z_k): its plane n_k . x = delta_k written so that
          a ray x = t r_p, r_p = ((u - cx) / fx, (v - cy) / fy, 1), meets it at 1 / t = q_k . r_p

and the rasteriser blends them as extra colour channels on a zero background: N(p) = sum_k w_k n_k and
Q(p) = sum_k w_k q_k (w_k the blend weights, A(p) = sum_k w_k). The depth D(p) = A / (Q . r_p) follows each
Gaussian's plane across its footprint, so the normal of the depth map

    N_D(p) = -(P(u + 1, v) - P(u - 1, v)) x (P(u, v + 1) - P(u, v - 1)) / |.|,   P = D r_p

agrees with the Gaussians' own normals where neighbouring planes meet along one surface, and the loss

    L_n = mean over pixels with A > 1/2 of  A - N . N_D  =  sum_k w_k (1 - n_k . N_D)

is the 2DGS term (0 when every blended Gaussian is tangent to the depth map's surface).

Depth distortion (2DGS eq. 13, sum_{i,j} w_i w_j (z_i - z_j)^2: the blended Gaussians drawn together along the
ray), in inverse depth: Gaussian k meets the ray of pixel p at s_k(p) = q_k . r_p, linear in r_p, so with the
blended outer products M(p) = sum_k w_k q_k q_k^T (6 more channels) the rasteriser's sums give it exactly,

    sum_{i,j} w_i w_j (s_i - s_j)^2 = 2 (A r_p^T M r_p - (Q . r_p)^2)

and, scaled by D^2 (held constant), the spread of the depths relative to the depth, (dz / z)^2, the same on a
scene of any size:

    e(p) = 2 (A r_p^T M r_p - (Q . r_p)^2) D^2        (about 2 A^2 var(z) / z^2 over the ray's blend weights)
    L_d  = mean over pixels with A > 1/2 of  e(p) [e(p) < EDGE_SPREAD]

A pixel whose depths spread wider (a relative std above about 2%) is a depth edge, a ray that passes a
silhouette onto what lies behind it: 2DGS's term would pull the two surfaces together there and, at any weight
that flattens the surfaces, tear the colours (the procedural scene: 17.3 dB held out at weight 100, 26.5 without). Those
pixels are left to the photometric loss, and the term thins the surfaces: on the procedural scene at weight 100
the mesh's distance to the exact surfaces went from 0.58 to 0.47 grid cells (docs: Export).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from nerfkit.models.splat.project import quaternion_to_rotation, world_to_camera

SURFACE_CHANNELS = 6  # N (3) and Q (3), after the colour channels
DISTORTION_CHANNELS = 6  # M's entries (00, 01, 02, 11, 12, 22), after those
EDGE_SPREAD = 1e-3  # pixels whose relative depth spread e(p) reaches this are depth edges, not in L_d
DELTA_MIN = 0.05  # |delta_k| >= this x z_k: a plane seen edge-on does not send 1 / t towards 0
INV_DEPTH_MIN = 1e-3  # pixels where Q . r_p falls below this (no plane in front) are left out


def surface_channels(means: jax.Array, log_scales: jax.Array, quats: jax.Array, c2w: jax.Array) -> jax.Array:
    """[N, 6]: (n_k, q_k) of each Gaussian in the camera axes of c2w [4, 4] (OpenGL; module docstring)."""
    view, origin = world_to_camera(c2w)
    rot = quaternion_to_rotation(quats)  # columns: the Gaussian's axes, world frame
    short = jnp.argmin(log_scales, axis=-1)
    n = jnp.take_along_axis(rot, short[:, None, None], axis=2)[..., 0] @ view.T
    mu = (means - origin) @ view.T
    n = jnp.where(jnp.sum(n * mu, -1, keepdims=True) > 0, -n, n)
    delta = jnp.minimum(jnp.sum(n * mu, -1), -DELTA_MIN * jnp.maximum(mu[:, 2], 1e-6))
    return jnp.concatenate([n, n / delta[:, None]], axis=-1)


def outer_channels(q: jax.Array) -> jax.Array:
    """[N, 6]: the entries (00, 01, 02, 11, 12, 22) of q_k q_k^T for q [N, 3]."""
    i, j = (0, 0, 0, 1, 1, 2), (0, 1, 2, 1, 2, 2)
    return q[:, i] * q[:, j]


def with_surface_channels(colors: jax.Array, background: jax.Array, params: dict, c2w: jax.Array,
                          distortion: bool = False):
    """(colors [N, C + K], background [C + K]): the colour channels followed by surface_channels (K = 6) and, with
    distortion, outer_channels of their q (K = 12), on zero."""
    extra = surface_channels(params["means"], params["log_scales"], params["quats"], c2w)
    if distortion:
        extra = jnp.concatenate([extra, outer_channels(extra[:, 3:])], axis=-1)
    return (jnp.concatenate([colors, extra], axis=-1),
            jnp.concatenate([background, jnp.zeros(extra.shape[-1], background.dtype)]))


def pixel_directions(intrinsics, width: int, height: int) -> jax.Array:
    """r_p [H, W, 3] = ((u - cx) / fx, (v - cy) / fy, 1) at the pixel centres (u, v) = (j + 1/2, i + 1/2)."""
    fx, fy, cx, cy = (intrinsics[i] for i in range(4))
    u = jnp.arange(width, dtype=jnp.float32) + 0.5
    v = jnp.arange(height, dtype=jnp.float32) + 0.5
    x = jnp.broadcast_to(((u - cx) / fx)[None, :], (height, width))
    y = jnp.broadcast_to(((v - cy) / fy)[:, None], (height, width))
    return jnp.stack([x, y, jnp.ones_like(x)], axis=-1)


def depth_normals(depth: jax.Array, rays: jax.Array) -> jax.Array:
    """N_D [H - 2, W - 2, 3] (unit, facing the camera) of the z-depth map depth [H, W] whose pixels look along
    rays [H, W, 3] (z = 1): central differences of the back-projected points P = depth r."""
    p = depth[..., None] * rays
    du = p[1:-1, 2:] - p[1:-1, :-2]
    dv = p[2:, 1:-1] - p[:-2, 1:-1]
    n = -jnp.cross(du, dv)
    return n * jax.lax.rsqrt(jnp.maximum(jnp.sum(n * n, -1, keepdims=True), 1e-24))  # finite gradients at n = 0


def plane_depth(channels: jax.Array, alpha: jax.Array, rays: jax.Array):
    """(Q . r_p [H, W], ok [H, W], D [H, W]) of a render's surface channels [H, W, >= 6] and opacity alpha [H, W],
    rays r_p [H, W, 3] (pixel_directions): the depth D = A / (Q . r_p) on the blended planes, at the pixels more
    than half opaque with a plane in front (ok; D = 0 elsewhere)."""
    inv = jnp.sum(channels[..., 3:6] * rays, -1)  # Q . r_p = A / D
    ok = (alpha > 0.5) & (inv > INV_DEPTH_MIN * alpha)
    return inv, ok, jnp.where(ok, alpha / jnp.where(ok, inv, 1.0), 0.0)


def normal_consistency(channels: jax.Array, alpha: jax.Array, intrinsics) -> jax.Array:
    """L_n (module docstring) of a render's surface channels [H, W, 6] (N, Q blended on a zero background) and
    opacity alpha [H, W]; 0 where no interior pixel is more than half opaque."""
    height, width = alpha.shape
    rays = pixel_directions(intrinsics, width, height)
    _, ok, depth = plane_depth(channels, alpha, rays)
    nd = depth_normals(depth, rays)
    inner = jax.lax.stop_gradient(ok[1:-1, 1:-1] & ok[2:, 1:-1] & ok[:-2, 1:-1] & ok[1:-1, 2:] & ok[1:-1, :-2])
    term = alpha[1:-1, 1:-1] - jnp.sum(channels[1:-1, 1:-1, :3] * nd, -1)
    return jnp.sum(jnp.where(inner, term, 0.0)) / jnp.maximum(jnp.sum(inner), 1)


def depth_distortion(channels: jax.Array, alpha: jax.Array, intrinsics) -> jax.Array:
    """L_d (module docstring) of a render's surface channels [H, W, 12] (N, Q, M blended on a zero background) and
    opacity alpha [H, W]: the mean over the pixels more than half opaque, depth edges counting 0."""
    height, width = alpha.shape
    rays = pixel_directions(intrinsics, width, height)
    inv, ok, depth = plane_depth(channels, alpha, rays)
    depth = jax.lax.stop_gradient(depth)
    x, y = rays[..., 0], rays[..., 1]
    m = [channels[..., 6 + c] for c in range(DISTORTION_CHANNELS)]
    second = m[0] * x * x + 2 * m[1] * x * y + 2 * m[2] * x + m[3] * y * y + 2 * m[4] * y + m[5]  # r^T M r
    spread = 2 * (alpha * second - inv * inv) * depth * depth
    counted = ok & (jax.lax.stop_gradient(spread) < EDGE_SPREAD)
    return jnp.sum(jnp.where(counted, spread, 0.0)) / jnp.maximum(jnp.sum(ok), 1)
