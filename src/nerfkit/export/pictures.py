"""Pictures of exports for the run report (matplotlib, headless): a shaded mesh and a point cloud,
each from two sides, drawn in the normalised frame (up = +z, so every capture looks upright)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

from nerfkit.export.surface import simplify

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

VIEWS = ((20, -60), (20, 120))  # (elevation, azimuth) of the two sides
LIGHT = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
MAX_PICTURE_FACES = 20000
MAX_PICTURE_POINTS = 40000


def _limits(ax, pts: np.ndarray) -> None:
    lo, hi = np.percentile(pts, 0.5, axis=0), np.percentile(pts, 99.5, axis=0)
    c, r = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-6) * 1.05
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1), zoom=1.5)
    ax.set_axis_off()


def _save(fig, path: Path, title: str) -> Path:
    fig.suptitle(title)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.93, wspace=0)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def shaded_face_colors(verts: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """RGB [F, 3] in [0, 1]: mean vertex colour times (0.45 + 0.55 |n . l|) for face normal n."""
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    base = colors[faces, :3].astype(np.float32).mean(axis=1) / 255.0
    return np.clip(base * (0.45 + 0.55 * np.abs(n @ LIGHT))[:, None], 0, 1)


def mesh_picture(path: Path, verts: np.ndarray, faces: np.ndarray, colors: np.ndarray, title: str) -> Path:
    """PNG of a vertex-coloured mesh from two sides (a decimated copy when it has more than
    MAX_PICTURE_FACES faces; matplotlib sorts polygons by depth, so this is a preview)."""
    if len(faces) > MAX_PICTURE_FACES:
        from scipy.spatial import cKDTree

        small_v, small_f = simplify(verts, faces, MAX_PICTURE_FACES)
        colors = colors[cKDTree(verts).query(small_v)[1]]  # colour of the nearest original vertex
        verts, faces = small_v, small_f
    face_rgb = shaded_face_colors(verts, faces, colors)
    fig = plt.figure(figsize=(12, 6), dpi=100)
    for k, (elev, azim) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(verts[faces], facecolors=face_rgb, edgecolors="none", linewidths=0))
        _limits(ax, verts)
        ax.view_init(elev=elev, azim=azim)
    return _save(fig, path, title)


def pointcloud_picture(path: Path, points: np.ndarray, colors: np.ndarray, title: str) -> Path:
    """PNG of a coloured point cloud [N, 3] (colours uint8 [N, 3]) from two sides."""
    rng = np.random.default_rng(0)
    keep = rng.permutation(len(points))[:MAX_PICTURE_POINTS]
    pts, col = points[keep], colors[keep, :3] / 255.0
    fig = plt.figure(figsize=(12, 6), dpi=100)
    for k, (elev, azim) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.6, c=col, depthshade=False, linewidths=0)
        _limits(ax, pts)
        ax.view_init(elev=elev, azim=azim)
    return _save(fig, path, title)
