"""Undistortion (nerfkit.data.undistort): a photo of the procedural scene taken through a distorted lens,
resampled, is the photo the pinhole camera takes from the same place; the loader does it when asked."""

import pytest

from nerfkit.core.metrics import psnr
from nerfkit.data.loader import load_frames, read_capture
from nerfkit.data.procedural.captures import make_capture, render, ring_poses
from nerfkit.data.undistort import pinhole_cameras, undistort_image
from nerfkit.rays.cameras import Camera

SIZE = 128
# An OPENCV lens with strong barrel distortion (the corners move ~9 px at 128 px) and a little decentring.
LENS = Camera.from_colmap("OPENCV", SIZE, SIZE, [110.0, 112.0, 63.0, 65.0, -0.18, 0.03, 0.002, -0.001])


def test_the_undistorted_photo_is_the_pinhole_photo():
    pin = LENS.undistorted()
    assert pin.model == "PINHOLE" and not pin.distorted and (pin.fx, pin.fy) == (LENS.fx, LENS.fy)
    c2w = ring_poses(3, seed=1)[1]
    photo, _, _ = render(c2w, LENS, env=True)
    truth, _, _ = render(c2w, pin, env=True)
    ours = undistort_image(photo, LENS, pin)
    assert ours.shape == truth.shape
    # Against the exact pinhole render: the renders are point-sampled (aliased checkerboards), which bilinear
    # resampling blurs a little (measured 28.9 dB; cubic: 28.4). The photo taken as if its lens were a pinhole
    # (no undistortion, resampled to the same size) is far off (measured 23.4 dB).
    good = psnr(ours, truth)
    as_is = undistort_image(photo, Camera(SIZE, SIZE, LENS.fx, LENS.fy, LENS.cx, LENS.cy), pin)
    assert good >= 27.5 and good >= psnr(as_is, truth) + 4.0, (good, psnr(as_is, truth))


def test_a_pinhole_camera_is_left_alone_and_mixed_sizes_are_cut_alike():
    plain = Camera.pinhole(40, 30, 35.0)
    assert plain.undistorted() is plain and pinhole_cameras([plain, plain]) == [plain, plain]
    other = Camera.from_colmap("OPENCV", SIZE, SIZE, [110.0, 112.0, 63.0, 65.0, -0.05, 0.0, 0.0, 0.0])
    a, b = pinhole_cameras([LENS, other])
    assert (a.width, a.height) == (b.width, b.height)
    assert (a.width, a.height) == (min(LENS.undistorted().width, other.undistorted().width),
                                   min(LENS.undistorted().height, other.undistorted().height))


@pytest.mark.parametrize("fmt", ["nerfstudio", "colmap"])
def test_the_loader_undistorts_only_when_asked(tmp_path, fmt):
    root = make_capture(tmp_path / fmt, fmt, n_views=3, camera=LENS, environment=True)
    cap = read_capture(root, "all")
    kept = load_frames(cap, "all")
    flat = load_frames(cap, "all", undistort=True)
    assert kept.cameras[0] == LENS and kept.images.shape[1:3] == (SIZE, SIZE)
    pin = LENS.undistorted()
    assert flat.cameras == [pin] * 3 and flat.images.shape[1:3] == (pin.height, pin.width)
    truth, _, _ = render(cap.frames("all")[0].c2w, pin, env=True)
    assert psnr(flat.images[0], truth) >= 26.5  # measured 27.6 dB (this view), see above
