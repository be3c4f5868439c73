"""Photos of the procedural scene for the structure-from-motion tests (process-data, the first hour)."""

from __future__ import annotations

import math

import numpy as np

from nerfkit.data.procedural import scene as proc
from nerfkit.data.procedural.captures import render
from nerfkit.rays.cameras import Camera


def arc_photos(n: int = 10, size: int = 192) -> list[np.ndarray]:
    """n uint8 photos [size, size, 3] of the procedural scene (with its textured surround) along a short arc,
    5 degrees apart: close enough for SIFT to match its repetitive textures (a full ring is not)."""
    cam = Camera.pinhole(size, size, 0.5 * size / math.tan(0.5 * proc.CAMERA_ANGLE_X))
    frames = [render(proc.orbit_pose(math.radians(5 * k), math.radians(30 + 5 * (k % 2))), cam, env=True)[0]
              for k in range(n)]
    return [np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8) for rgb in frames]
