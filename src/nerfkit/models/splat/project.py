"""Projection of 3D Gaussians to the image (EWA splatting; Zwicker et al. 2002, Kerbl et al. 2023).

A Gaussian has a world mean mu [3], log-scales s [3], a rotation quaternion q = (w, x, y, z)
[4] (normalised here) and covariance

    Sigma = R(q) S S^T R(q)^T,   S = diag(exp(s)).

Cameras follow nerfkit's conventions (cameras.py): camera-to-world c2w [4, 4] in OpenGL axes
(looking down -z, +y up), pinhole intrinsics fx, fy, cx, cy, and pixel (row i, col j) centred
at image coordinates (u, v) = (j + 0.5, i + 0.5). In OpenCV camera axes (x right, y down,
z forward = z-depth) a world point p has

    p_c = V (p - o),   V = diag(1, -1, -1) R^T   (R = c2w[:3, :3], o = c2w[:3, 3])
    u = fx x_c / z_c + cx,   v = fy y_c / z_c + cy,

which is exactly the inverse of the pixel rays of cameras.py, so a splat rendered here lines
up pixel-for-pixel with a NeRF render of the same camera. The image-space covariance is the
local affine approximation of the projection (EWA), plus a low-pass dilation:

    J = [[fx / z, 0, -fx x / z^2], [0, fy / z, -fy y / z^2]]   at (x, y, z) = p_c
    Sigma' = J V Sigma V^T J^T + delta * I_2,   delta = LOWPASS_DILATION (px^2) by default.

A view rendered at a fraction r of its photo's resolution (coarse to fine trains at r = 1/2) takes
delta = LOWPASS_DILATION r^2: the same 0.3 px^2 footprint measured in the photo's pixels, so that
Gaussians fitted small are not eroded by a floor four times wider than the one they render with.

As in the paper's code, x / z and y / z inside J are clamped to FOV_CLAMP times the image's
half-extent, so Gaussians far outside the view do not get huge footprints. Everything here
is plain JAX, differentiated by autodiff; radii are integers and carry no gradient.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.encoding.sh import sh_encode

LOWPASS_DILATION = 0.3  # px^2 added to the 2D covariance's diagonal (3DGS's anti-aliasing floor)
NEAR_PLANE = 0.01  # Gaussians whose centre has z-depth <= this are culled
FOV_CLAMP = 1.3  # J is evaluated at x/z, y/z clamped to 1.3 x the image's half-extent
SIGMA_CUTOFF = 3.0  # radius = ceil(3 sqrt(lambda_max)); the rasteriser cuts at 3 sigma (Mahalanobis)
SH_C0 = 0.28209479177387814  # Y_0 = 1 / (2 sqrt(pi)): colour = SH_C0 * dc + 0.5 at degree 0


def rotation_entries(q) -> list[list]:
    """R(q) entry by entry: R[i][j] [...] of quaternions q [..., 4] = (w, x, y, z), normalised first. A numpy q
    stays numpy, in its own precision (depth.rotations: float64), a JAX one JAX."""
    xp = np if isinstance(q, np.ndarray) else jnp
    q = q / xp.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def quaternion_to_rotation(q: jax.Array) -> jax.Array:
    """Rotation matrices [..., 3, 3] of quaternions q [..., 4] = (w, x, y, z), normalised first."""
    return jnp.stack([jnp.stack(r, axis=-1) for r in rotation_entries(q)], axis=-2)


def covariance_3d(log_scales: jax.Array, quats: jax.Array) -> jax.Array:
    """Sigma = R S S^T R^T [..., 3, 3] from log-scales [..., 3] and quaternions [..., 4]."""
    m = quaternion_to_rotation(quats) * jnp.exp(log_scales)[..., None, :]  # R S
    return m @ jnp.swapaxes(m, -1, -2)


def world_to_camera(c2w: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(V [3, 3], o [3]) with p_c = V (p - o) in OpenCV axes for an OpenGL camera-to-world c2w [4, 4]."""
    flip = jnp.array([1.0, -1.0, -1.0], c2w.dtype)
    return flip[:, None] * c2w[:3, :3].T, c2w[:3, 3]


def conic_and_radius(cov2d: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Conic (a, b, c) [N, 3] with [[a, b], [b, c]] = Sigma'^{-1}, and radius [N] int32 =
    ceil(SIGMA_CUTOFF sqrt(lambda_max(Sigma'))) in pixels (no gradient)."""
    sa, sb, sc = cov2d[:, 0, 0], cov2d[:, 0, 1], cov2d[:, 1, 1]
    det = sa * sc - sb * sb  # > 0: Sigma' >= dilation I
    conic = jnp.stack([sc / det, -sb / det, sa / det], axis=-1)
    sa, sc, det = (jax.lax.stop_gradient(x) for x in (sa, sc, det))
    mid = 0.5 * (sa + sc)
    lam_max = mid + jnp.sqrt(jnp.maximum(mid * mid - det, 0.0))
    return conic, jnp.ceil(SIGMA_CUTOFF * jnp.sqrt(lam_max)).astype(jnp.int32)


def project_gaussians(means, log_scales, quats, c2w, intrinsics, width: int, height: int,
                      dilation: float = LOWPASS_DILATION) -> dict:
    """Project N Gaussians into a pinhole camera.

    Args:
      means [N, 3], log_scales [N, 3], quats [N, 4] (w first): the Gaussians, world space.
      c2w [4, 4]: camera-to-world, OpenGL axes. intrinsics: (fx, fy, cx, cy), floats or
      scalar arrays. width, height: image size in pixels (static). dilation: the low-pass floor
      added to Sigma' in px^2 (module docstring).

    Returns dict: means2d [N, 2] (u, v) pixel coordinates, conics [N, 3], depths [N] (z-depth),
    radii [N] int32 (0: culled, i.e. z <= NEAR_PLANE or the radius square misses the image),
    cov2d [N, 2, 2]. Culled Gaussians keep finite (meaningless) values in the other outputs.

    Computed entry by entry on [N] arrays, with Sigma' = P P^T + delta I, P = J V R S [N, 2, 3] (the same
    as J V Sigma V^T J^T): XLA:CPU fuses that, and its gradient, into a few loops over the Gaussians, where
    the matrix form's batched 3x3 products ran as many small matrix products, in about twice the time
    (CHANGELOG, issue 41).
    """
    view, origin = world_to_camera(c2w)
    rel = [means[:, i] - origin[i] for i in range(3)]
    x, y, z = (view[r, 0] * rel[0] + view[r, 1] * rel[1] + view[r, 2] * rel[2] for r in range(3))
    valid = z > NEAR_PLANE
    x, y, z = jnp.where(valid, x, 0.0), jnp.where(valid, y, 0.0), jnp.where(valid, z, 1.0)  # finite if culled
    fx, fy, cx, cy = intrinsics
    means2d = jnp.stack([fx * x / z + cx, fy * y / z + cy], axis=-1)
    rot, scale = rotation_entries(quats), [jnp.exp(log_scales[:, j]) for j in range(3)]
    vrs = [[sum(view[i, k] * rot[k][j] for k in range(3)) * scale[j] for j in range(3)] for i in range(3)]  # V R S
    tx = jnp.clip(x / z, -FOV_CLAMP * cx / fx, FOV_CLAMP * (width - cx) / fx) * z
    ty = jnp.clip(y / z, -FOV_CLAMP * cy / fy, FOV_CLAMP * (height - cy) / fy) * z
    # J = [[fx / z, 0, -fx tx / z^2], [0, fy / z, -fy ty / z^2]]; P = J (V R S)
    p0 = [fx / z * vrs[0][j] - fx * tx / (z * z) * vrs[2][j] for j in range(3)]
    p1 = [fy / z * vrs[1][j] - fy * ty / (z * z) * vrs[2][j] for j in range(3)]
    sa = p0[0] * p0[0] + p0[1] * p0[1] + p0[2] * p0[2] + dilation
    sb = p0[0] * p1[0] + p0[1] * p1[1] + p0[2] * p1[2]
    sc = p1[0] * p1[0] + p1[1] * p1[1] + p1[2] * p1[2] + dilation
    cov2d = jnp.stack([jnp.stack([sa, sb], axis=-1), jnp.stack([sb, sc], axis=-1)], axis=-2)
    conics, radii = conic_and_radius(cov2d)
    m = jax.lax.stop_gradient(means2d)
    inside = ((m[:, 0] + radii > 0) & (m[:, 0] - radii < width) & (m[:, 1] + radii > 0) & (m[:, 1] - radii < height))
    radii = jnp.where(valid & inside, radii, 0)
    return {"means2d": means2d, "conics": conics, "depths": z, "radii": radii, "cov2d": cov2d}


def sh_colors(sh: jax.Array, means: jax.Array, cam_center: jax.Array, degree: int) -> jax.Array:
    """View-dependent colours [N, C] = max(sum_k sh[:, k] Y_k(d) + 0.5, 0) (3DGS's convention).

    sh [N, K, C] coefficients (K >= (degree + 1)^2; band l of the real SH basis of
    encoding/sh.py, the same basis and signs as 3DGS), means [N, 3], cam_center [3],
    degree 0..3 (static); d = (mu - o) / |mu - o| is the unit view direction. Float32.
    """
    if not 0 <= degree <= 3:
        raise ValueError(f"SH degree must be 0..3, got {degree}")
    n_coef = (degree + 1) ** 2
    d = means - cam_center
    d = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
    basis = sh_encode(d, degree + 1)  # [N, n_coef]
    return jnp.maximum(jnp.einsum("nk,nkc->nc", basis, sh[:, :n_coef]) + 0.5, 0.0)
