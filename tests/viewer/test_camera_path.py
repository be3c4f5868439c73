"""Camera paths: nerfstudio's camera_path.json layout, smooth interpolation through keyframes."""

import json
import math

import numpy as np
import pytest

from nerfkit.core.errors import DataError
from nerfkit.rays.camera_path import (
    focal_from_fov_y,
    interpolate,
    read_camera_path,
    write_camera_path,
)
from nerfkit.rays.cameras import look_at


def ring(k, radius=4.0, z=1.0):
    return np.stack([look_at(np.array([radius * math.cos(a), radius * math.sin(a), z]), np.zeros(3)).astype(np.float64)
                     for a in np.linspace(0, 2 * math.pi, k, endpoint=False)])


def test_frames_pass_through_the_keyframes_and_stay_rigid():
    keys = ring(3)
    frames, fovs = interpolate(keys[:3], np.array([40.0, 50.0, 60.0]), 9)
    np.testing.assert_allclose(frames[[0, 4, 8]], keys, atol=1e-9)  # keyframe k at time k / (K - 1)
    np.testing.assert_allclose(fovs, np.linspace(40, 60, 9))
    r = frames[:, :3, :3]
    np.testing.assert_allclose(r @ np.transpose(r, (0, 2, 1)), np.broadcast_to(np.eye(3), r.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-9)


def test_a_cycle_through_a_ring_of_keyframes_stays_near_the_circle_and_closes():
    frames, _ = interpolate(ring(8), np.full(8, 50.0), 64, cycle=True)
    radius = np.linalg.norm(frames[:, :2, 3], axis=-1)
    assert np.abs(radius - 4.0).max() < 0.05  # a spline through 8 points of a circle hugs it
    np.testing.assert_allclose(frames[:, 2, 3], 1.0, atol=1e-9)
    step = np.linalg.norm(np.diff(np.concatenate([frames[:, :3, 3], frames[:1, :3, 3]]), axis=0), axis=-1)
    assert step.max() / step.min() < 1.2  # evenly paced, including the wrap-around


def test_write_then_read_in_nerfstudio_layout(tmp_path):
    keys = ring(4)
    p = write_camera_path(tmp_path / "camera_path.json", list(keys), [50.0] * 4, 320, 240, seconds=2.0, fps=10)
    meta = json.loads(p.read_text())
    assert meta["render_width"] == 320 and meta["render_height"] == 240 and len(meta["camera_path"]) == 20
    assert len(meta["camera_path"][0]["camera_to_world"]) == 16 and len(meta["keyframes"]) == 4
    got = read_camera_path(p)
    assert got["c2w"].shape == (20, 4, 4) and (got["width"], got["height"], got["fps"]) == (320, 240, 10)
    np.testing.assert_allclose(got["c2w"][0], keys[0], atol=1e-9)
    assert focal_from_fov_y(90.0, 240) == pytest.approx(120.0)


def test_reads_a_path_written_by_nerfstudio(tmp_path):
    # The fields ns-render reads, as nerfstudio's viewer writes them (row-major 4x4, vertical fov in degrees).
    c2w = look_at(np.array([0.0, -3.0, 1.0]), np.zeros(3)).astype(float)
    ns = {"keyframes": [], "camera_type": "perspective", "render_height": 480, "render_width": 640,
          "camera_path": [{"camera_to_world": c2w.ravel().tolist(), "fov": 50, "aspect": 4 / 3}] * 3,
          "fps": 24, "seconds": 0.125, "smoothness_value": 0.5, "is_cycle": False, "crop": None}
    (tmp_path / "ns.json").write_text(json.dumps(ns))
    got = read_camera_path(tmp_path / "ns.json")
    assert got["c2w"].shape == (3, 4, 4) and (got["width"], got["height"]) == (640, 480)
    np.testing.assert_allclose(got["c2w"][1], c2w)


ONE = '{"camera_to_world": [1,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1], "fov": 50}'


@pytest.mark.parametrize("text,match", [
    ("{", "not a readable camera path JSON"),
    ('{"camera_path": []}', "no 'camera_path' list"),
    ('{"camera_path": [{"fov": 50}]}', r"camera_path\[0\] needs 'camera_to_world'"),
    ('{"camera_path": [{"camera_to_world": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "fov": 0}]}', "fov outside"),
    (f'{{"camera_path": [{ONE}], "fps": 0}}', "'fps' must be a number 1-240"),
    (f'{{"camera_path": [{ONE}], "fps": -24}}', "'fps' must be a number 1-240"),
    (f'{{"camera_path": [{ONE}], "fps": "24"}}', "'fps' must be a number 1-240"),
    (f'{{"camera_path": [{ONE}], "render_width": 100000}}', "'render_width' must be a whole number 1-8192"),
    (f'{{"camera_path": [{ONE}], "render_height": 480.5}}', "'render_height' must be a whole number"),
    (f'{{"camera_path": [{ONE}], "render_height": true}}', "'render_height' must be a whole number"),
    ('{"camera_path": [{"camera_to_world": [1,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1], "fov": 50, "aspect": "wide"}]}',
     "'aspect' must make a width"),
    ('{"camera_path": [{"camera_to_world": [1,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1], "fov": 50, "aspect": 1000}]}',
     "'aspect' must make a width"),
])
def test_bad_camera_paths_are_one_line_errors(tmp_path, text, match):
    (tmp_path / "p.json").write_text(text)
    with pytest.raises(DataError, match=match) as e:
        read_camera_path(tmp_path / "p.json")
    assert "\n" not in str(e.value)


def test_a_path_may_leave_its_size_and_fps_out_or_give_a_video_rate(tmp_path):
    p = tmp_path / "p.json"
    p.write_text(f'{{"camera_path": [{ONE}], "render_height": 240.0, "fps": 29.97}}')
    got = read_camera_path(p)
    assert (got["width"], got["height"], got["fps"]) == (240, 240, 29.97) and isinstance(got["height"], int)
    p.write_text(f'{{"camera_path": [{ONE}], "render_width": null}}')
    got = read_camera_path(p)
    assert (got["width"], got["height"], got["fps"]) == (480, 480, 24)
    p.write_text('{"camera_path": [{"camera_to_world": [1,0,0,0, 0,1,0,0, 0,0,1,4, 0,0,0,1], "fov": 50, "aspect": 2}]}')
    assert read_camera_path(p)["width"] == 960
