"""Sparse SfM points: reading them (a .ply cloud or a COLMAP model) and moving them by a similarity; points
on a far sphere coloured by the photos (a background to start splats of unbounded scenes from)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def transform_points(points: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """x' = A x + t for points [N, 3] and a [4, 4] transform [[A, t], [0, 1]] (float64)."""
    t = np.asarray(transform, np.float64)
    return np.asarray(points, np.float64) @ t[:3, :3].T + t[:3, 3]


def read_points(path: str | Path, transform: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(points [N, 3] float64, colours [N, 3] float32 in [0, 1]) of an SfM cloud.

    path: a .ply point cloud (x, y, z and red, green, blue, as nerfkit's sparse_pc.ply or a
    COLMAP export; grey without colours), or a COLMAP sparse model folder (points3D.bin/txt).
    transform: optional [4, 4] similarity applied to the points, e.g. SceneData.transform to
    bring capture coordinates into nerfkit's normalised frame."""
    path = Path(path)
    if path.is_dir():
        from nerfkit.rays.colmap_compat import (
            pycolmap,  # deferred: pycolmap loads only for a COLMAP model
        )

        rec = pycolmap.Reconstruction(str(path))
        pts = np.array([p.xyz for p in rec.points3D.values()], np.float64).reshape(-1, 3)
        cols = np.array([p.color for p in rec.points3D.values()], np.float32).reshape(-1, 3) / 255.0
    else:
        from plyfile import PlyData

        v = PlyData.read(str(path))["vertex"]
        names = v.data.dtype.names
        pts = np.stack([v["x"], v["y"], v["z"]], -1).astype(np.float64)
        if all(c in names for c in ("red", "green", "blue")):
            raw = np.stack([v["red"], v["green"], v["blue"]], -1)
            cols = raw.astype(np.float32) / (255.0 if raw.dtype.kind in "ui" else 1.0)
        else:
            cols = np.full((len(pts), 3), 0.5, np.float32)
    return (pts if transform is None else transform_points(pts, transform)), cols


def far_radius(poses: np.ndarray, points: np.ndarray | None, factor: float, quantile: float) -> float:
    """The far sphere's radius in the normalised frame: factor x the farthest camera's distance from the origin
    (poses [V, 4, 4]), or, where the SfM points [N, 3] reach further, the `quantile` of their distances from it,
    so that a background drawn on the sphere lies at or beyond what SfM saw, not in front of it. A forward-facing
    capture's far wall can lie many camera distances away (the procedural one at 96 px: the cameras within 6
    units, the wall's points at 47-68, the sphere of 3 x 6 a third of the way to it); a ring of cameras in a room
    keeps factor x its radius unless SfM saw beyond it."""
    r = factor * float(np.linalg.norm(np.asarray(poses)[:, :3, 3], axis=1).max())
    if points is None or len(points) == 0:
        return r
    return max(r, float(np.quantile(np.linalg.norm(np.asarray(points, np.float64), axis=1), quantile)))


def far_sphere_points(n: int, radius: float, poses: np.ndarray, cameras: list, images: np.ndarray,
                      seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(points [M, 3], colours [M, 3] in [0, 1]), M <= n: points uniform on the sphere |x| = radius (the
    normalised frame's origin is the point the cameras look at), each coloured by the pixel of the first
    training photo (poses [V, 4, 4], cameras, images [V, H, W, 3]) it projects into; the ones no photo sees
    are dropped."""
    from nerfkit.rays.cameras import project_points

    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    pts = radius * x / np.linalg.norm(x, axis=1, keepdims=True)
    colours = np.full((n, 3), np.nan, np.float32)
    for c2w, cam, img in zip(poses, cameras, images):
        todo = np.isnan(colours[:, 0])
        if not todo.any():
            break
        u, v, front = project_points(pts[todo], np.asarray(c2w, np.float64), cam)
        h, w = img.shape[:2]
        inside = front & (u >= 0) & (u < min(w, cam.width)) & (v >= 0) & (v < min(h, cam.height))
        rows = np.flatnonzero(todo)[inside]
        colours[rows] = img[v[inside].astype(int), u[inside].astype(int), :3]
    seen = ~np.isnan(colours[:, 0])
    return pts[seen], colours[seen]


def far_points_through_photos(n: int, radius: float, poses: np.ndarray, cameras: list, images: np.ndarray,
                              seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(points [n, 3], colours [n, 3] in [0, 1]) where the rays of n pixels, drawn uniformly over the
    training photos (poses [V, 4, 4], cameras, images [V, H, W, 3]), leave the sphere |x| = radius (every
    camera inside it): x = o + t d with t = -o.d + sqrt((o.d)^2 - |o|^2 + radius^2) for unit d; each coloured
    by its pixel. For a forward-facing capture, whose photos see a small cap of that sphere (far_sphere_points
    would keep a few percent of its points), every point is one a photo sees."""
    from nerfkit.rays.cameras import camera_rays

    rng = np.random.default_rng(seed)
    views = rng.integers(0, len(poses), n)
    pts = np.zeros((n, 3), np.float64)
    colours = np.zeros((n, 3), np.float32)
    for k in np.unique(views):
        rows = np.flatnonzero(views == k)
        cam, img = cameras[k], images[k]
        h, w = min(img.shape[0], cam.height), min(img.shape[1], cam.width)
        flat = rng.integers(0, h * w, len(rows))
        o, d = camera_rays(np.asarray(poses[k], np.float64), cam)
        o, d = o[:h, :w].reshape(-1, 3)[flat].astype(np.float64), d[:h, :w].reshape(-1, 3)[flat].astype(np.float64)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        b = np.einsum("ij,ij->i", o, d)
        t = -b + np.sqrt(np.maximum(b * b - np.einsum("ij,ij->i", o, o) + radius**2, 0.0))
        pts[rows] = o + t[:, None] * d
        colours[rows] = img.reshape(-1, img.shape[-1])[(flat // w) * img.shape[1] + flat % w, :3]
    return pts, colours
