"""The procedural scene's exact surfaces (scene.py's solids), for measuring meshes against them: the signed
distance to the union of the solids and its outward normal."""

from __future__ import annotations

import numpy as np

from nerfkit.data.procedural.scene import (
    BIG_SPHERE_CENTER,
    BIG_SPHERE_RADIUS,
    BOX_MAX,
    BOX_MIN,
    CYLINDER_CENTER_XY,
    CYLINDER_RADIUS,
    CYLINDER_Z_RANGE,
    GROUND_RADIUS,
    GROUND_Z_RANGE,
    SMALL_SPHERE_CENTER,
    SMALL_SPHERE_RADIUS,
)


def signed_distance(p: np.ndarray) -> np.ndarray:
    """Signed distance [N] from points [N, 3] to the surface of the union of the scene's solids, negative inside
    (exact outside the solids; inside, the distance to the enclosing solid's own boundary)."""
    def sphere(c, r):
        return np.linalg.norm(p - c, axis=-1) - r

    def box(lo, hi):
        q = np.abs(p - (lo + hi) / 2) - (hi - lo) / 2
        return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)

    def cylinder(cxy, r, z):
        q = np.stack([np.linalg.norm(p[:, :2] - cxy, axis=-1) - r, np.abs(p[:, 2] - (z[0] + z[1]) / 2)
                      - (z[1] - z[0]) / 2], -1)
        return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)

    sdf = np.minimum.reduce([
        sphere(BIG_SPHERE_CENTER, BIG_SPHERE_RADIUS),
        sphere(SMALL_SPHERE_CENTER, SMALL_SPHERE_RADIUS),
        box(BOX_MIN, BOX_MAX), cylinder(CYLINDER_CENTER_XY, CYLINDER_RADIUS, CYLINDER_Z_RANGE),
        cylinder(np.zeros(2), GROUND_RADIUS, GROUND_Z_RANGE)])
    return sdf


def surface_normal(p: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """The outward unit normal [N, 3] of the nearest solid's surface at points [N, 3]: the gradient of
    signed_distance by central differences (undefined exactly on an edge; the mean of the two faces' there)."""
    grad = np.stack([signed_distance(p + e) - signed_distance(p - e) for e in np.eye(3) * eps], -1)
    return grad / np.maximum(np.linalg.norm(grad, axis=-1, keepdims=True), 1e-12)
