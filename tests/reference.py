"""Small helpers kept for the tests only (references and conveniences no nerfkit module needs)."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.data.formats.blender import iter_frames
from nerfkit.data.loader import load_scene
from nerfkit.data.procedural.surfaces import signed_distance
from nerfkit.rays.cameras import (
    Camera,
    camera_rays,
    pinhole_directions,
    rotate_directions,
)
from nerfkit.sampling.occupancy import OccupancyConfig, cell_coords


def pixel_directions(i, j, height: int, width: int, focal):
    """Camera-space directions [..., 3] of pixel centres at rows i, cols j of the ideal
    camera `Camera.pinhole(width, height, focal)` (any array module)."""
    return pinhole_directions(i, j, focal, focal, 0.5 * width, 0.5 * height)


def rays_from_pixels(c2w, i, j, height: int, width: int, focal):
    """World-space rays through pixels (i, j) of ideal pinhole cameras c2w [..., 4, 4]: origins, directions."""
    return rotate_directions(c2w, pixel_directions(i, j, height, width, focal))


def image_rays(c2w: np.ndarray, height: int, width: int, focal: float) -> tuple[np.ndarray, np.ndarray]:
    """All pixel-centre rays of an ideal pinhole camera: origins, directions of shape [H, W, 3]."""
    return camera_rays(c2w, Camera.pinhole(width, height, focal))


def uncontract(y: jnp.ndarray) -> jnp.ndarray:
    """The inverse of coord.contract on the open ball |y| < 2: x = y / (|y| (2 - |y|)) outside the unit ball."""
    n = jnp.maximum(jnp.linalg.norm(y, axis=-1, keepdims=True), 1e-12)
    return jnp.where(n <= 1.0, y, y / (n * jnp.maximum(2.0 - n, 1e-6)))


def cell_centers(cfg: OccupancyConfig) -> jax.Array:
    """World-space centres of all occupancy cells, -B + (ijk + 1/2) h: float32 [R^3, 3] (row c: flat cell c)."""
    ijk = cell_coords(jnp.arange(cfg.n_cells, dtype=jnp.int32), cfg)
    return (-cfg.bound + (ijk.astype(jnp.float32) + 0.5) * cfg.cell_size).astype(jnp.float32)


def read_split_poses(root: str | Path, spec: str) -> tuple[np.ndarray, float]:
    """Poses [N, 4, 4] and camera_angle_x of a Blender split spec, without reading images."""
    poses, fov = [], None
    for _, _, pose, fov, _ in iter_frames(root, spec):
        poses.append(pose)
    if not poses:
        raise DataError(f"{root}: split spec {spec!r} selects no frames")
    return np.stack(poses), fov


def load_blender(root: str | Path, spec: str, *, downscale: int | None = None, target_width: int | None = None,
                 background: str = "white"):
    """The frames a split spec (e.g. "train,val[0:50]") selects from a Blender-format folder, loaded."""
    return load_scene(root, spec, format="blender", downscale=downscale, target_width=target_width,
                      background=background)


def surface_distance(p: np.ndarray) -> np.ndarray:
    """Unsigned distance [N] from points [N, 3] to the surface of the union of the scene's solids
    (exact outside the solids; inside, the distance to the enclosing solid's own boundary)."""
    return np.abs(signed_distance(p))



def texture_against_vertex_colours(textured, plain) -> tuple[np.ndarray, float, float]:
    """A textured mesh (trimesh, uv atlas) against the vertex-coloured export of the same surface: (distance [V'] of
    each textured vertex to the nearest plain vertex, the mean |texture read at the vertex's uv - that vertex's
    colour| over the channels, the same for one flat colour (the vertex colours' mean): the score to beat)."""
    from scipy.spatial import cKDTree

    gap, near = cKDTree(np.asarray(plain.vertices)).query(np.asarray(textured.vertices))
    baked = textured.visual.to_color().vertex_colors[:, :3] / 255.0
    painted = plain.visual.vertex_colors[:, :3] / 255.0
    return gap, float(np.abs(baked - painted[near]).mean()), float(np.abs(painted - painted.mean(0)).mean())
