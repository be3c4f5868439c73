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


def _solid_terms(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sdf [K, N], edge [K, N]) for points p [N, 3] and the scene's K solids: each solid's own signed distance,
    and the distance from p's nearest point on that solid to the solid's own edges (a box's 12 edges, a
    cylinder's two rims; inf for a sphere). With q the box's |p - c| - half-extent (or a cylinder's
    (radial, axial) excess), a point on a face has q_max = 0 and lies -q_j from the face's border along j,
    so edge = max(-(second largest q), 0) (a cylinder: max(-min q, 0))."""
    def sphere(c, r):
        return np.linalg.norm(p - c, axis=-1) - r, np.full(len(p), np.inf)

    def solid(q):
        sdf = np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0)
        return sdf, np.maximum(-np.sort(q, axis=-1)[:, -2], 0.0)

    def box(lo, hi):
        return solid(np.abs(p - (lo + hi) / 2) - (hi - lo) / 2)

    def cylinder(cxy, r, z):
        return solid(np.stack([np.linalg.norm(p[:, :2] - cxy, axis=-1) - r,
                               np.abs(p[:, 2] - (z[0] + z[1]) / 2) - (z[1] - z[0]) / 2], -1))

    terms = [sphere(BIG_SPHERE_CENTER, BIG_SPHERE_RADIUS), sphere(SMALL_SPHERE_CENTER, SMALL_SPHERE_RADIUS),
             box(BOX_MIN, BOX_MAX), cylinder(CYLINDER_CENTER_XY, CYLINDER_RADIUS, CYLINDER_Z_RANGE),
             cylinder(np.zeros(2), GROUND_RADIUS, GROUND_Z_RANGE)]
    return np.stack([t[0] for t in terms]), np.stack([t[1] for t in terms])


def signed_distance(p: np.ndarray) -> np.ndarray:
    """Signed distance [N] from points [N, 3] to the surface of the union of the scene's solids, negative inside
    (exact outside the solids; inside, the distance to the enclosing solid's own boundary)."""
    return _solid_terms(p)[0].min(0)


def crease_distance(p: np.ndarray) -> np.ndarray:
    """Distance [N] from points p [N, 3] near the surface to its nearest crease, where the true normal jumps: the
    edges of the nearest solid k (_solid_terms) or where another solid meets it, min(edge_k, min_{j != k}
    |sdf_j|) (the second term is at most the distance to the curve where the two surfaces meet). A mesh on a
    grid of cell h rounds a crease over about a cell, so normals are measured away from them."""
    sdf, edge = _solid_terms(p)
    k = np.argmin(sdf, axis=0)
    n = np.arange(len(p))
    others = np.abs(sdf)
    others[k, n] = np.inf
    return np.minimum(edge[k, n], others.min(0))


def surface_normal(p: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """The outward unit normal [N, 3] of the nearest solid's surface at points [N, 3]: the gradient of
    signed_distance by central differences (undefined exactly on an edge; the mean of the two faces' there)."""
    grad = np.stack([signed_distance(p + e) - signed_distance(p - e) for e in np.eye(3) * eps], -1)
    return grad / np.maximum(np.linalg.norm(grad, axis=-1, keepdims=True), 1e-12)
