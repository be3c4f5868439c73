"""Photos of a lens-distorted camera resampled as a pinhole camera saw them, for methods that render pinhole
cameras only (Gaussian splats: Supports.lens False). The radiance fields model the lens instead (each pixel's
ray goes through the camera's own unprojection, rays/cameras.py) and keep the photos as they are.

The pinhole camera is COLMAP's choice (Camera.undistorted: the same focal lengths, the largest image whose
every pixel sees inside the photo). Pixel (i, j) of it, centre (u, v) = (j + 1/2, i + 1/2), looks along the
normalised direction

    (x, y) = ((u - cx) / fx, (v - cy) / fy)

which the lens (pycolmap's img_from_cam) puts at (u', v') in the photo; its value is the photo's bilinear
interpolation there (scipy.ndimage.map_coordinates, order 1, at row v' - 1/2, column u' - 1/2; the edge pixels
repeated for the sub-pixel rim).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from nerfkit.rays.cameras import Camera


@lru_cache(maxsize=8)
def source_coords(src: Camera, dst: Camera) -> np.ndarray:
    """[2, dst.height, dst.width] float32: the (row, column) in src's image (pixel-centre convention, as
    map_coordinates indexes) that pixel (i, j) of the pinhole camera dst shows (module docstring)."""
    v, u = np.meshgrid(np.arange(dst.height) + 0.5, np.arange(dst.width) + 0.5, indexing="ij")
    us, vs = src.project((u - dst.cx) / dst.fx, (v - dst.cy) / dst.fy)
    return np.stack([vs - 0.5, us - 0.5]).astype(np.float32)


def undistort_image(image: np.ndarray, src: Camera, dst: Camera) -> np.ndarray:
    """image [src.height, src.width, ...] (float) seen through the pinhole camera dst: [dst.height, dst.width,
    ...] (module docstring)."""
    from scipy import ndimage  # deferred: it costs every command's start-up

    coords = source_coords(src, dst)
    flat = image.reshape(image.shape[0], image.shape[1], -1)
    out = np.stack([ndimage.map_coordinates(flat[..., c], coords, order=1, mode="nearest")
                    for c in range(flat.shape[-1])], -1)
    return out.reshape(dst.height, dst.width, *image.shape[2:]).astype(image.dtype)


def pinhole_cameras(cameras: list[Camera]) -> list[Camera]:
    """The undistorted camera of each (Camera.undistorted), all cut to one size where they differ (the smallest
    width and height, centred: a pinhole camera cropped is a pinhole camera with its principal point moved);
    the cameras themselves when none is distorted."""
    if not any(c.distorted for c in cameras):
        return list(cameras)
    out = [c.undistorted() for c in cameras]
    w, h = min(c.width for c in out), min(c.height for c in out)
    return [c if (c.width, c.height) == (w, h) else
            Camera(w, h, c.fx, c.fy, c.cx - (c.width - w) / 2, c.cy - (c.height - h) / 2) for c in out]
