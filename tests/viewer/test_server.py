"""The viewer's per-browser state (viewer/server.py)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from nerfkit.viewer.frames import view_camera
from nerfkit.viewer.server import _Client


def test_a_zero_height_canvas_keeps_the_last_aspect():
    """viser can report a 0 px high canvas while the page resizes; its aspect would divide by zero."""
    cam = SimpleNamespace(image_width=640, image_height=480)
    st = _Client(SimpleNamespace(camera=cam))
    assert st.aspect == 1.0
    st.note_camera()
    assert st.version == 1 and st.aspect == pytest.approx(4 / 3)
    cam.image_width, cam.image_height = 640, 0
    st.note_camera()
    assert st.version == 2 and st.aspect == pytest.approx(4 / 3)
    view_camera(math.radians(50), st.aspect, 256)  # and a camera can be made from it
