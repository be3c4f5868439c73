"""A video to walk `nerfkit process-data video` through when no phone video is at hand: a smooth orbit around the
procedural scene inside its far textured surround (an unbounded scene, every pixel covered), rendered through pixel
centres and encoded as H.264, as a phone would hand it over.

    python benchmarks/procedural_video.py [--out runs/video/room.mp4] [--frames 240] [--width 640] [--height 480]

The camera circles the objects once at 4 units, 65 degrees across, its elevation rising and falling between 18 and
38 degrees twice per turn; 30 frames per second. It is not a phone's video (no motion blur, no rolling shutter, no
exposure changes, an exact pinhole lens): it exercises the video path, it does not stand for a real capture.
benchmarks/own_photos.py --video FILE then runs the README's path on it.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from nerfkit.data.procedural import scene as proc
from nerfkit.data.procedural.captures import render
from nerfkit.rays.cameras import Camera

FOV_DEGREES = 65.0
RADIUS = 4.0


def orbit(k: int, n: int) -> np.ndarray:
    """Camera-to-world pose [4, 4] of frame k of n (see the module docstring)."""
    a = 2 * math.pi * k / n
    return proc.orbit_pose(a, math.radians(28 + 10 * math.sin(2 * a)), RADIUS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("runs/video/room.mp4"))
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    a = ap.parse_args()
    cam = Camera.pinhole(a.width, a.height, 0.5 * a.width / math.tan(math.radians(FOV_DEGREES) / 2))
    t0 = time.perf_counter()
    frames = [np.round(np.clip(render(orbit(k, a.frames), cam, True)[0], 0, 1) * 255).astype(np.uint8)
              for k in range(a.frames)]
    a.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(a.out, np.stack(frames), fps=30, codec="libx264", quality=8)
    print(f"wrote {a.out}: {a.frames} frames of {a.width}x{a.height} in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
