"""The surface depth of a splat render, for the exports (TSDF fusion, mesh quality): each pixel's median
depth, read on the plane of the Gaussian where its ray turns half opaque.

A render's expected depth sum_k w_k z_k / alpha mixes the Gaussians a ray passes; the depth of one
Gaussian's centre z_k is constant over its whole footprint, so a surface tiled by wide Gaussians comes
out as steps (a crumpled mesh). Instead, pixel p's ray r(t) = t r_p (OpenCV camera axes, t the z-depth,
r_p = ((u - cx) / fx, (v - cy) / fy, 1)) meets Gaussian k's density exp(-(x - mu)^T P (x - mu) / 2),
P = Sigma^{-1} (in camera axes: P_c = V P V^T, mu_c = V (mu - o), project.world_to_camera), at its
maximum

    t*_k(p) = r_p^T P_c mu_c / r_p^T P_c r_p

which for a flat Gaussian (one scale -> 0) is where the ray crosses its plane: the depth 2DGS reads off
its surfels, and a smooth function of the pixel for any Gaussian (RaDe-GS, Zhang et al. 2024). t* is kept
within z_k +- SPAN x the Gaussian's largest scale (a ray grazing a flat Gaussian meets its plane far away).

The median depth of pixel p is t*_m(p) of the first Gaussian m (front to back, the rasteriser's order
and alpha test) after which the running opacity 1 - T reaches half the pixel's final opacity A: the
ray models' median (render/volume.py), which a soft edge does not pull towards the background. What the
exports read is a robust version of it, the mean of the ray's depth quantile function over the central
band of opacity [(1/2 - BAND) A, (1/2 + BAND) A] (BAND = 1/4: the interquartile mean):

    d(p) = sum_k |[c_k, c_k + w_k] n band| t*_k(p) / (2 BAND A),     c_k = 1 - T_k (the opacity before k)

Where neighbouring pixels' medians fall on different Gaussians the median jumps between their planes;
the band mean blends them. On the procedural scene's exact depth (a 4-minute splat run, 128 px), the
normals of the band mean's depth maps were within 10 degrees of the truth on 63% of pixels against 56%
for the median, with the same share within 1% of the box side.
"""

from __future__ import annotations

from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import tiles_numba
from nerfkit.models.splat.project import LOWPASS_DILATION, project_gaussians, rotation_entries

SPAN = 3.0  # t* stays within z_k +- SPAN x the largest scale of Gaussian k
BAND = 0.25  # the exported depth: the mean depth over running opacities [(1/2 - BAND) A, (1/2 + BAND) A]
MIN_LOG_SCALE = -12.0  # scales are floored at e^-12 before P = Sigma^{-1} is formed (float64)


def depth_planes(params: dict, c2w: np.ndarray, intrinsics) -> np.ndarray:
    """planes [N, 15] float64 for depth_kernels.median_tiles: (P00, P01, P02, P11, P12, P22, (P mu)_0..2,
    fx, fy, cx, cy, z_lo, z_hi) of each Gaussian in the OpenCV axes of the camera c2w [4, 4] (OpenGL)
    with intrinsics (fx, fy, cx, cy): P = Sigma^{-1} and mu in camera axes, [z_lo, z_hi] = z +- SPAN max scale."""
    c2w = np.asarray(c2w, np.float64)
    view = np.array([1.0, -1.0, -1.0])[:, None] * c2w[:3, :3].T
    mu = (np.asarray(params["means"], np.float64) - c2w[:3, 3]) @ view.T
    log_s = np.maximum(np.asarray(params["log_scales"], np.float64), MIN_LOG_SCALE)
    rot = view @ rotations(params["quats"])  # [N, 3, 3], camera axes
    prec = (rot * np.exp(-2.0 * log_s)[:, None, :]) @ np.swapaxes(rot, 1, 2)  # R diag(e^-2s) R^T
    pmu = np.einsum("nij,nj->ni", prec, mu)
    reach = SPAN * np.exp(log_s.max(axis=1))
    n = len(mu)
    return np.concatenate([prec[:, 0, 0:3], prec[:, 1, 1:3], prec[:, 2, 2:3], pmu,
                           np.broadcast_to(np.asarray(intrinsics, np.float64), (n, 4)),
                           (mu[:, 2] - reach)[:, None], (mu[:, 2] + reach)[:, None]], axis=1)


def rotations(quats: np.ndarray) -> np.ndarray:
    """Rotation matrices [N, 3, 3] (float64) of quaternions [N, 4] = (w, x, y, z), normalised in float64 (project.py's
    formula): orthonormal to float64 precision, so that P of a flat Gaussian does not leak its huge eigenvalue into
    the other axes, as a float32 rotation would."""
    return np.stack([np.stack(row, -1) for row in rotation_entries(np.asarray(quats, np.float64))], -2)


@lru_cache(maxsize=16)
def _project_jit(width: int, height: int, dilation: float):
    def run(means, log_scales, quats, c2w, intrinsics):
        p = project_gaussians(means, log_scales, quats, c2w, tuple(intrinsics[i] for i in range(4)), width, height,
                              dilation)
        return p["means2d"], p["conics"], p["depths"], p["radii"]
    return jax.jit(run)


def median_depth(params: dict, c2w: np.ndarray, intrinsics, width: int, height: int, alpha: np.ndarray,
                 threads: int | None = None, band: float = BAND, dilation: float = LOWPASS_DILATION) -> np.ndarray:
    """The median depth [H, W] (float32; 0 where alpha = 0) of the Gaussians params (numpy, PARAM_NAMES) seen
    by the pinhole camera (c2w [4, 4] OpenGL, intrinsics (fx, fy, cx, cy), width x height) whose render has
    opacity alpha [H, W]: the mean over the opacity band of half-width `band` around A / 2 (0: the median
    itself; module docstring), the Gaussians drawn with the screen floor `dilation` px^2 that rendered alpha. Runs
    the CPU tile kernel whatever backend rendered alpha."""
    means2d, conics, depths, radii = (np.asarray(a) for a in _project_jit(int(width), int(height), float(dilation))(
        *(jnp.asarray(params[k], jnp.float32) for k in ("means", "log_scales", "quats")),
        jnp.asarray(c2w, jnp.float32), jnp.asarray(intrinsics, jnp.float32)))
    opac = 1.0 / (1.0 + np.exp(-np.asarray(params["opacity"], np.float64)))
    planes = depth_planes(params, c2w, intrinsics)
    t_final = 1.0 - np.asarray(alpha, np.float64)
    return tiles_numba.median_depth(means2d, conics, opac, depths, radii, planes, width, height, t_final,
                                    threads, band).astype(np.float32)

