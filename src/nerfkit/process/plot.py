"""A picture of recovered cameras and sparse points, from two sides, to judge SfM at a glance."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nerfkit.data.normalize import apply_transform, normalizing_transform  # noqa: E402
from nerfkit.rays.cameras import Camera  # noqa: E402


def frustum_lines(c2w: np.ndarray, cam: Camera, size: float) -> list[np.ndarray]:
    """Line segments [2, 3] of a camera pyramid (OpenGL c2w) whose image plane sits `size` in front."""
    corners = []
    for u, v in ((0, 0), (cam.width, 0), (cam.width, cam.height), (0, cam.height)):
        d = np.array([(u - cam.cx) / cam.fx, -(v - cam.cy) / cam.fy, -1.0]) * size
        corners.append(c2w[:3, :3] @ d + c2w[:3, 3])
    o = c2w[:3, 3]
    segs = [np.stack([o, c]) for c in corners]
    segs += [np.stack([corners[k], corners[(k + 1) % 4]]) for k in range(4)]
    return segs


def plot_cameras(path: Path, c2ws: np.ndarray, cameras: list[Camera], points: np.ndarray | None = None,
                 colors: np.ndarray | None = None, title: str = "", max_points: int = 20000) -> Path:
    """Write a PNG with the camera frustums (first one red) and the points, seen from two sides.

    Everything is shown in the normalised frame nerfkit trains in (cameras around the origin,
    mean up = +z), so the picture looks the same whatever coordinates SfM chose."""
    m, s = normalizing_transform(c2ws)
    poses = apply_transform(m, s, c2ws)
    fig = plt.figure(figsize=(12, 6), dpi=100)
    pts = None
    if points is not None and len(points):
        rng = np.random.default_rng(0)
        keep = rng.permutation(len(points))[:max_points]
        pts = np.asarray(points, np.float64)[keep] @ m[:3, :3].T + m[:3, 3]
        col = None if colors is None else np.asarray(colors)[keep] / 255.0
        lim = np.percentile(np.abs(pts), 98) * 1.2
        inside = np.all(np.abs(pts) <= lim, axis=1)
        pts, col = pts[inside], (None if col is None else col[inside])
    for k, (elev, azim) in enumerate(((25, -60), (80, 30))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        if pts is not None:
            ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.5, c=col if col is not None else "0.3", depthshade=False)
        for n, (pose, cam) in enumerate(zip(poses, cameras)):
            for seg in frustum_lines(pose, cam, 0.4):
                ax.plot(*seg.T, color="tab:red" if n == 0 else "tab:blue", linewidth=0.8)
        ext = np.abs(poses[:, :3, 3]).max() * 1.1
        ax.set_xlim(-ext, ext)
        ax.set_ylim(-ext, ext)
        ax.set_zlim(-ext, ext)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
    fig.suptitle(title or f"{len(poses)} cameras" + (f", {len(pts)} points" if pts is not None else ""))
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
