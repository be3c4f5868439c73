"""The viewer's pure pieces: viser's cameras in nerfkit's convention, what a view mode shows, and how
previews adapt to keep their frame rate (server.py's docstring tells the story).

Cameras. viser reports a camera as position + wxyz quaternion of an OpenCV frame (x right,
y down, z forward) in world coordinates; nerfkit's c2w is OpenGL (x right, y up, camera looks
down -z), so c2w[:3, :3] = R_viser diag(1, -1, -1). `fov` is vertical, in radians.
"""

from __future__ import annotations

import math

import numpy as np

from nerfkit.core.viz import colorize_depth, depth_range
from nerfkit.rays.cameras import Camera

FLIP_YZ = np.diag([1.0, -1.0, -1.0])
MODES = ("RGB", "Depth", "Opacity")
DRAWN_BY = ("browser (viser splats)", "nerfkit (server)")  # who draws a splat run


def c2w_from_viser(wxyz, position) -> np.ndarray:
    """OpenGL camera-to-world [4, 4] of a viser camera (wxyz quaternion of an OpenCV frame, position [3])."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = np.asarray(wxyz, np.float64)
    c2w = np.eye(4)
    c2w[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix() @ FLIP_YZ
    c2w[:3, 3] = np.asarray(position, np.float64)
    return c2w


def viser_from_c2w(c2w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(wxyz [4], position [3]) of the OpenCV frame of an OpenGL camera-to-world [4, 4] (or [3, 4])."""
    from scipy.spatial.transform import Rotation

    c2w = np.asarray(c2w, np.float64)
    x, y, z, w = Rotation.from_matrix(c2w[:3, :3] @ FLIP_YZ).as_quat()
    return np.array([w, x, y, z]), c2w[:3, 3].copy()


def view_camera(fov_y: float, aspect: float, max_side: int) -> Camera:
    """A pinhole camera of vertical field of view fov_y (radians), aspect W / H, longest side max_side."""
    if aspect >= 1.0:
        w, h = max_side, max(1, round(max_side / aspect))
    else:
        w, h = max(1, round(max_side * aspect)), max_side
    return Camera.pinhole(w, h, 0.5 * h / math.tan(0.5 * fov_y))


def shade_output(out: dict, mode: str, background) -> np.ndarray:
    """The [H, W, 3] image a view mode shows: RGB, turbo-coloured depth (this frame's range), or opacity."""
    if mode == "Depth":
        lo, hi = depth_range([out["depth_normalized"]], [out["opacity"]])
        return colorize_depth(out["depth_normalized"], out["opacity"], lo, hi, background)
    if mode == "Opacity":
        return np.repeat(out["opacity"][..., None], 3, axis=-1)
    return out["rgb"]


def preview_size(side: int, seconds: float, target: float, full: int, lo: int = 16) -> int:
    """The next preview's longer side after one of `side` px took `seconds`: render time ~ pixels ~ side^2,
    so side * sqrt(target / seconds), at most doubled or halved per frame, within [lo, full]."""
    scale = min(2.0, max(0.5, math.sqrt(target / max(seconds, 1e-6))))
    return int(min(full, max(lo, round(side * scale))))


def preview_quality(stride: int, side: int, seconds: float, target: float, full: int,
                    max_stride: int) -> tuple[int, int]:
    """The next preview's (march stride, side) after one at (stride, side) took `seconds`, for `target`
    seconds a frame. Resolution matters more than the march: a frame that is too slow (> 1.2 target)
    or smaller than `full` first coarsens the march, up to max_stride; at the coarsest march the side
    follows the target (preview_size, both ways); at full resolution, a fast frame (< 0.6 target)
    refines the march. One stride changes the time by less than 2x, so the band between the two
    thresholds keeps the march from flapping."""
    if stride < max_stride and (seconds > 1.2 * target or side < full):
        return stride + 1, side
    if stride == max_stride and (side < full or seconds > target):
        return stride, preview_size(side, seconds, target, full)
    if side == full and seconds < 0.6 * target:
        return max(1, stride - 1), side
    return stride, side
