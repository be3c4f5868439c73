"""Viewer helpers (viewer/frames.py): camera conventions between viser and nerfkit, view cameras, output modes,
preview quality."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nerfkit.rays.cameras import camera_rays, look_at
from nerfkit.viewer.frames import (
    c2w_from_viser,
    preview_quality,
    preview_size,
    shade_output,
    view_camera,
    viser_from_c2w,
)


@pytest.mark.parametrize("eye", [(4.0, 0.5, 1.0), (-1.0, 3.0, -2.0), (0.0, 0.1, 5.0)])
def test_viser_camera_round_trip_and_convention(eye):
    c2w = look_at(np.array(eye), np.zeros(3)).astype(np.float64)
    wxyz, pos = viser_from_c2w(c2w)
    assert abs(np.linalg.norm(wxyz) - 1) < 1e-9
    back = c2w_from_viser(wxyz, pos)
    np.testing.assert_allclose(back, c2w, atol=1e-6)
    # viser's frame is OpenCV: its +z axis (forward) is nerfkit's viewing direction -z_gl, toward the target.
    from scipy.spatial.transform import Rotation

    r = Rotation.from_quat([*wxyz[1:], wxyz[0]]).as_matrix()
    forward = -np.asarray(eye) / np.linalg.norm(eye)
    np.testing.assert_allclose(r[:, 2], forward, atol=1e-6)
    np.testing.assert_allclose(r[:, 1], -c2w[:3, 1], atol=1e-6)  # image y points down


def test_view_camera_size_and_field_of_view():
    cam = view_camera(math.radians(60), 16 / 9, 256)
    assert (cam.width, cam.height) == (256, 144)
    cam = view_camera(math.radians(60), 0.5, 256)
    assert (cam.width, cam.height) == (128, 256)
    # The top edge ray makes half the vertical field of view with the axis.
    _, d = camera_rays(np.eye(4, dtype=np.float32), view_camera(math.radians(50), 1.0, 64))
    top = d[0, 32] / np.linalg.norm(d[0, 32])
    assert abs(math.degrees(math.atan2(top[1], -top[2])) - 25) < 0.5  # half a pixel's angle


def test_output_modes():
    out = {"rgb": np.full((4, 5, 3), 0.3, np.float32), "depth_normalized": np.linspace(1, 2, 20).reshape(4, 5),
           "opacity": np.full((4, 5), 0.25, np.float32)}
    out["opacity"][0, 0] = 1.0
    assert np.allclose(shade_output(out, "RGB", (1, 1, 1)), 0.3)
    op = shade_output(out, "Opacity", (1, 1, 1))
    assert op.shape == (4, 5, 3) and np.allclose(op[..., 0], out["opacity"])
    dep = shade_output(out, "Depth", (1, 1, 1))
    assert dep.shape == (4, 5, 3) and np.all((dep >= 0) & (dep <= 1))


def test_preview_size_converges_to_the_target_frame_time():
    """With render time proportional to pixels (t = c side^2), the adapted preview side reaches the one
    that renders in the target time, and stays within [16, full]."""
    c, target, full = 8e-6, 1 / 6, 512  # 8 us per pixel: the target side is sqrt(target / c) ~ 144 px
    side = 64
    for _ in range(12):
        side = preview_size(side, c * side**2, target, full)
    assert abs(side - math.sqrt(target / c)) <= 2
    assert preview_size(400, 0.01, target, full) == 512  # a fast machine previews at full resolution
    assert preview_size(20, 10.0, target, full) == 16
    assert preview_size(100, 100.0, target, full) == 50  # at most halved per frame


@pytest.mark.parametrize("speed", [1.0, 10.0, 0.1])
def test_preview_quality_coarsens_the_march_before_the_resolution(speed):
    """Render times of lego at 256 px measured at march strides 1-3 (0.35, 0.21, 0.15 s), scaled by side^2
    and by a machine `speed`: previews settle at full resolution with the finest march that keeps the
    target frame time, and drop resolution only when the coarsest march is too slow."""
    per_stride = {1: 0.35, 2: 0.21, 3: 0.15}
    target, full = 1 / 6, 256

    def seconds(stride, side):
        return per_stride[stride] * (side / 256) ** 2 / speed

    stride, side = 1, 64
    for _ in range(30):
        stride, side = preview_quality(stride, side, seconds(stride, side), target, full, 3)
    if speed == 1.0:  # this machine: stride 3 at 256 px takes 0.15 s (6.7 frames/s)
        assert (stride, side) == (3, 256)
    elif speed == 10.0:  # fast: the full march at full resolution
        assert (stride, side) == (1, 256)
    else:  # slow: the coarsest march, and a side that renders near the target time
        assert stride == 3 and side < full
        assert 0.6 * target <= seconds(stride, side) <= 1.2 * target
    # steady: the setting holds
    assert preview_quality(stride, side, seconds(stride, side), target, full, 3) == (stride, side)
