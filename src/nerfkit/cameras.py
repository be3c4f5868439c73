"""Pinhole cameras and rays (OpenGL convention: camera looks down -z, +y up, x right).

For pixel (row i, col j) of an H x W image with focal length f (pixels), the ray through
the pixel centre has, in camera coordinates,

    d_cam = ((j + 0.5 - W/2) / f,  -(i + 0.5 - H/2) / f,  -1)

and in world coordinates d = R d_cam, o = c2w[:3, 3]. Directions are NOT normalised, so
the ray parameter t of a point o + t d is its depth along the camera's viewing axis
(z-depth): near/far bounds and rendered depth maps are in that unit.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np


def pixel_directions(i, j, height: int, width: int, focal):
    """Camera-space directions [..., 3] of pixel centres at rows i, cols j (any array module)."""
    xp = jnp if isinstance(i, jnp.ndarray) else np
    x = (j + 0.5 - 0.5 * width) / focal
    y = -(i + 0.5 - 0.5 * height) / focal
    return xp.stack([x, y, -xp.ones_like(x)], axis=-1)


def rays_from_pixels(c2w, i, j, height: int, width: int, focal):
    """World-space rays through pixels (i, j) of cameras c2w [..., 4, 4] (broadcast with i, j).

    Returns origins, directions, both [..., 3].
    """
    xp = jnp if isinstance(c2w, jnp.ndarray) or isinstance(i, jnp.ndarray) else np
    d_cam = pixel_directions(i, j, height, width, focal)
    rot = c2w[..., :3, :3]
    d = xp.sum(rot * d_cam[..., None, :], axis=-1)
    o = xp.broadcast_to(c2w[..., :3, 3], d.shape)
    return o, d


def image_rays(c2w: np.ndarray, height: int, width: int, focal: float) -> tuple[np.ndarray, np.ndarray]:
    """All pixel-centre rays of one camera: origins, directions of shape [H, W, 3]."""
    i, j = np.meshgrid(np.arange(height, dtype=np.float32), np.arange(width, dtype=np.float32), indexing="ij")
    o, d = rays_from_pixels(np.asarray(c2w, np.float32)[None, None], i, j, height, width, focal)
    return o.astype(np.float32), d.astype(np.float32)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> np.ndarray:
    """Camera-to-world matrix [4, 4] of a camera at `eye` looking at `target` (-z toward it)."""
    z = eye - target
    z = z / np.linalg.norm(z)
    x = np.cross(up, z)
    if np.linalg.norm(x) < 1e-8:  # looking straight along `up`: any perpendicular x will do
        x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, eye
    return m.astype(np.float32)


def scene_center(poses: np.ndarray) -> np.ndarray:
    """Least-squares point closest to all optical axes (the point cameras look at).

    Minimises sum_k |(I - a_k a_k^T)(p - o_k)|^2 for axes through o_k with unit direction a_k.
    """
    a = -poses[:, :3, 2].astype(np.float64)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    o = poses[:, :3, 3].astype(np.float64)
    proj = np.eye(3)[None] - a[:, :, None] * a[:, None, :]
    lhs = proj.sum(0)
    rhs = np.einsum("kij,kj->i", proj, o)
    if np.linalg.cond(lhs) > 1e8:  # all axes parallel: no closest point, use the mean camera position
        return o.mean(0)
    return np.linalg.solve(lhs, rhs)


def orbit_poses(poses: np.ndarray, n_frames: int) -> np.ndarray:
    """A circular orbit [n_frames, 4, 4] around the scene centre, world +z up.

    Radius and elevation are the medians of the given cameras' (the dataset's typical view).
    """
    center = scene_center(poses)
    rel = poses[:, :3, 3] - center
    radius = float(np.median(np.linalg.norm(rel, axis=-1)))
    elev = float(np.median(np.arcsin(np.clip(rel[:, 2] / np.linalg.norm(rel, axis=-1), -1, 1))))
    out = []
    for k in range(n_frames):
        az = 2 * math.pi * k / n_frames
        eye = center + radius * np.array([math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az), math.sin(elev)])
        out.append(look_at(eye, center))
    return np.stack(out)
