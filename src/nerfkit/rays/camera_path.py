"""Camera paths in nerfstudio's `camera_path.json` layout: keyframes in, smooth frames out.

    {"camera_type": "perspective", "render_width": W, "render_height": H, "fps": 24,
     "seconds": S, "is_cycle": false, "smoothness_value": 0.5,
     "keyframes": [{"matrix": [16 floats], "fov": deg, "aspect": W/H}, ...],
     "camera_path": [{"camera_to_world": [16 floats, row-major 4x4], "fov": deg, "aspect": a}, ...]}

`camera_to_world` is an OpenGL camera-to-world matrix (camera looks down -z) in the run's
coordinates; `fov` is the VERTICAL field of view in degrees, as nerfstudio writes it. A
renderer only needs `camera_path` (one entry per output frame, fps * seconds of them);
nerfkit writes keyframes too, and makes the frames from them: positions on a Catmull-Rom-
like cubic spline through the keyframe positions (scipy CubicSpline, periodic when the path
is a cycle), orientations by spherical linear interpolation between keyframes (scipy Slerp),
field of view linearly; keyframe k sits at time k / (K - 1) (k / K for cycles).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from nerfkit.core.errors import DataError


def interpolate(c2ws: np.ndarray, fovs: np.ndarray, n_frames: int,
                cycle: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """n_frames camera-to-world matrices [n, 4, 4] and fovs [n] through keyframes c2ws [K, 4, 4], fovs [K]."""
    from scipy.interpolate import CubicSpline
    from scipy.spatial.transform import Rotation, Slerp

    c2ws = np.asarray(c2ws, np.float64)
    fovs = np.asarray(fovs, np.float64)
    k = len(c2ws)
    if k == 1:
        return np.repeat(c2ws, n_frames, 0), np.repeat(fovs, n_frames)
    if cycle:
        c2ws = np.concatenate([c2ws, c2ws[:1]])
        fovs = np.concatenate([fovs, fovs[:1]])
    times = np.linspace(0.0, 1.0, len(c2ws))
    t = np.linspace(0.0, 1.0, n_frames, endpoint=not cycle)
    pos = CubicSpline(times, c2ws[:, :3, 3], axis=0, bc_type="periodic" if cycle else "natural")(t) \
        if len(c2ws) > 2 else np.stack([np.interp(t, times, c2ws[:, :3, 3][:, i]) for i in range(3)], -1)
    rot = Slerp(times, Rotation.from_matrix(c2ws[:, :3, :3]))(t).as_matrix()
    out = np.tile(np.eye(4), (n_frames, 1, 1))
    out[:, :3, :3], out[:, :3, 3] = rot, pos
    return out, np.interp(t, times, fovs)


def write_camera_path(path: Path, keyframes: list[np.ndarray], fovs: list[float], width: int, height: int,
                      seconds: float, fps: int = 24, cycle: bool = False) -> Path:
    """Write keyframes (c2w [4, 4], vertical fov in degrees) and the interpolated frames."""
    if not keyframes:
        raise DataError("a camera path needs at least one keyframe")
    n = max(1, round(seconds * fps))
    frames, ffovs = interpolate(np.stack(keyframes), np.asarray(fovs), n, cycle)
    aspect = width / height
    meta = {
        "camera_type": "perspective", "render_width": int(width), "render_height": int(height), "fps": int(fps),
        "seconds": float(seconds), "is_cycle": bool(cycle), "smoothness_value": 0.5,
        "keyframes": [{"matrix": np.asarray(c, float).ravel().tolist(), "fov": float(f), "aspect": aspect}
                      for c, f in zip(keyframes, fovs)],
        "camera_path": [{"camera_to_world": c.ravel().tolist(), "fov": float(f), "aspect": aspect}
                        for c, f in zip(frames, ffovs)],
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(meta, indent=2))
    return path


MAX_RENDER_SIZE = 8192  # pixels a side (8K video)
MAX_FPS = 240


def read_camera_path(path: Path) -> dict:
    """Frames of a camera_path.json: {"c2w": [N, 4, 4], "fov_y": [N] degrees, "width", "height", "fps"}. The size
    and fps are the file's (render_width, render_height at most MAX_RENDER_SIZE, fps 1-MAX_FPS); where it leaves
    them out, a height of 480, the width from the first frame's aspect ratio, 24 fps. DataError (one line, naming
    the file) for anything else."""
    path = Path(path)
    try:
        meta = json.loads(path.read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise DataError(f"{path}: no such camera path file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        raise DataError(f"{path}: not a readable camera path JSON ({type(e).__name__}); save it again from the "
                        f"viewer") from None
    frames = meta.get("camera_path") if isinstance(meta, dict) else None
    if not isinstance(frames, list) or not frames:
        raise DataError(f"{path}: no 'camera_path' list of frames (nerfstudio's camera_path.json layout)")
    c2w, fov = [], []
    for k, f in enumerate(frames):
        try:
            m = np.asarray(f["camera_to_world"], np.float64).reshape(4, 4)
            fv = float(f["fov"])
        except (KeyError, TypeError, ValueError):
            raise DataError(f"{path}: camera_path[{k}] needs 'camera_to_world' (16 numbers) and 'fov' (degrees)") \
                from None
        if not np.all(np.isfinite(m)) or not 0 < fv < 180:
            raise DataError(f"{path}: camera_path[{k}] has a non-finite matrix or a fov outside (0, 180) degrees")
        c2w.append(m)
        fov.append(fv)
    w = _setting(path, meta, "render_width", MAX_RENDER_SIZE)
    h = _setting(path, meta, "render_height", MAX_RENDER_SIZE)
    fps = _setting(path, meta, "fps", MAX_FPS, whole=False)
    h = 480 if h is None else h
    if w is None:  # the first frame's aspect ratio (width / height) gives it
        aspect = frames[0].get("aspect")  # (a dict: its "camera_to_world" was read above)
        aspect = 1.0 if aspect is None else aspect
        if isinstance(aspect, bool) or not isinstance(aspect, (int, float)) or not 0 < aspect * h <= MAX_RENDER_SIZE:
            raise DataError(f"{path}: camera_path[0]'s 'aspect' must make a width of 1-{MAX_RENDER_SIZE} pixels at a "
                            f"height of {h} (got {json.dumps(aspect)}); give 'render_width' or fix the aspect")
        w = max(1, round(h * aspect))
    return {"c2w": np.stack(c2w), "fov_y": np.asarray(fov), "width": w, "height": h, "fps": 24 if fps is None else fps}


def _setting(path: Path, meta: dict, key: str, top: int, whole: bool = True) -> int | float | None:
    """meta[key] as a number 1-top, a whole one unless `whole` is False (an fps of 29.97); None when the file
    leaves it out (or null); DataError naming the file and the key for anything else."""
    v = meta.get(key)
    if v is None:
        return None
    if (isinstance(v, bool) or not isinstance(v, (int, float)) or not 1 <= v <= top
            or (whole and not float(v).is_integer())):
        raise DataError(f"{path}: '{key}' must be a {'whole ' if whole else ''}number 1-{top} (got {json.dumps(v)}); "
                        f"fix it in the file or save the path again from the viewer")
    return int(v) if float(v).is_integer() else float(v)


def focal_from_fov_y(fov_y_deg: float, height: int) -> float:
    """Focal length in pixels of a vertical field of view: f = H / (2 tan(fov / 2))."""
    return 0.5 * height / math.tan(math.radians(fov_y_deg) / 2)
