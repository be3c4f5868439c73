"""The baked scene's WebGL page in a real browser, and the server of `nerfkit view --baked`.

Headless Chromium with software WebGL2 (SwiftShader; chromium.WEBGL_ARGS) opens the page of a small
baked procedural scene served by `start_server`, renders three training cameras through the page's
JS API (window.nerfkitBaked.render: RGBA8 pixels of exactly the camera asked for), and compares
them with the Python reference renderer of the format (BakedModel): the shader marches the same
samples, so only 8-bit rounding should differ. A screenshot of the page is kept
(NERFKIT_BAKE_SCREENSHOT=/path.png copies it out).
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import socket
import urllib.error
import urllib.request

import numpy as np
import pytest
from chromium import Chromium

from nerfkit.bake import web
from nerfkit.bake.bake import bake_run
from nerfkit.cli.main import main
from nerfkit.core.errors import ConfigError
from nerfkit.core.metrics import psnr
from nerfkit.models.baked.format import FORMAT, load_baked
from nerfkit.models.baked.model import BakedModel
from nerfkit.rays.cameras import Camera
from nerfkit.render.images import make_renderer

SIZE = 64  # rendered images, pixels (the procedural scene's own size)
VIEWS = (0, 8, 16)  # training cameras of the procedural run


@pytest.fixture(scope="module")
def baked(procedural_run, tmp_path_factory):
    """(run, baked folder) of the procedural run baked at 64^3 cells."""
    run = procedural_run[0]
    out = tmp_path_factory.mktemp("baked_web") / "scene"
    bake_run(run, out, resolution=64, sh_bands=2, finetune_minutes=0, progress=False, log=lambda *a: None)
    return run, out


def get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=30) as res:
        assert res.status == 200
        return res.read()


def test_page_renders_like_the_reference_in_headless_chromium(chromium, baked, procedural_run, tmp_path):
    run, out = baked
    b = load_baked(out)
    focal = json.loads((run / "scene.json").read_text())["focal"]
    cam = Camera.pinhole(SIZE, SIZE, focal)
    poses = [np.asarray(procedural_run[2][k], np.float32) for k in VIEWS]
    bm = BakedModel(b)
    bp, ba = bm.params_and_aux(b)
    ref = make_renderer(bm, 4096)
    server, url = web.start_server(out)
    browser = Chromium(chromium, tmp_path / "profile", 640, 480, webgl=True)
    try:
        browser.open_page()
        browser.navigate(url)
        info = browser.evaluate("window.nerfkitBaked.ready", timeout=120)
        assert info["bricks"] == b.meta["bricks"] and info["resolution"] == 64
        scores = []
        for pose in poses:
            want = ref.render_camera(bp, ba, pose, cam)["rgb"]
            assert want.std() > 0.05, "the reference image is blank: a bad test camera"
            arg = json.dumps({"c2w": pose.tolist(), "width": SIZE, "height": SIZE, "fx": cam.fx, "fy": cam.fy,
                              "cx": cam.cx, "cy": cam.cy})
            px = base64.b64decode(browser.evaluate(f"window.nerfkitBaked.render({arg})", timeout=120))
            got = np.frombuffer(px, np.uint8).reshape(SIZE, SIZE, 4)
            assert np.all(got[..., 3] == 255)
            scores.append(float(psnr(got[..., :3].astype(np.float32) / 255.0, want)))
        print("page vs reference PSNR (dB):", ", ".join(f"{s:.2f}" for s in scores))
        # Measured 62.3-62.9 dB: the same samples, up to 8-bit rounding and hardware trilinear weights.
        assert min(scores) >= 35.0, scores

        orbit_controls_move_the_view(browser)
        assert browser.evaluate("window.nerfkitBaked.draw()", timeout=120) > 0
        hud = browser.evaluate("document.getElementById('scene').textContent + ' | ' + "
                               "document.getElementById('timing').textContent")
        assert "MB" in hud and "ms/frame" in hud and "fps" in hud, hud
        errors = [e for e in browser.events if e.get("method") == "Runtime.exceptionThrown"]
        assert not errors, errors
        shot = tmp_path / "baked_web.png"
        browser.screenshot(shot)
    finally:
        browser.close()
        web.stop_server(server)

    import imageio.v3 as iio

    img = iio.imread(shot)
    assert img.shape[1] == 640 and float(np.std(img[..., :3])) > 10, "screenshot is blank"
    keep = os.environ.get("NERFKIT_BAKE_SCREENSHOT")
    if keep:
        shutil.copy(shot, keep)


def orbit_controls_move_the_view(browser):
    """Drag rotates, shift-drag pans, the wheel zooms (mouse events through DevTools)."""
    def mouse(kind, x, y, **kw):
        browser.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left", **kw})

    def drag(modifiers=0):
        mouse("mousePressed", 300, 200, clickCount=1, buttons=1, modifiers=modifiers)
        for k in range(1, 6):
            mouse("mouseMoved", 300 + 10 * k, 200 + 4 * k, buttons=1, modifiers=modifiers)
        mouse("mouseReleased", 350, 220, clickCount=1, modifiers=modifiers)
        return browser.evaluate("window.nerfkitBaked.view()")

    v0 = browser.evaluate("window.nerfkitBaked.view()")
    v1 = drag()
    assert v1["azimuth"] < v0["azimuth"] and v1["elevation"] > v0["elevation"] and v1["target"] == v0["target"]
    v2 = drag(modifiers=8)  # shift
    assert v2["target"] != v1["target"] and v2["azimuth"] == v1["azimuth"]
    browser.send("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": 300, "y": 200, "deltaX": 0, "deltaY": 200})
    v3 = browser.evaluate("window.nerfkitBaked.view()")
    assert v3["distance"] > v2["distance"]


def test_server_binds_loopback_and_serves_the_page_and_arrays(baked):
    _, out = baked
    server, url = web.start_server(out)
    try:
        assert server.server_address[0] == "127.0.0.1" and url.startswith("http://127.0.0.1:")
        assert b"baked.js" in get(url) and get(url + "index.html") == (out / "index.html").read_bytes()
        assert b"nerfkitBaked" in get(url + "baked.js")
        for name in ("baked.json", "index.npy", "density.npy", "sh.npy"):
            assert get(url + name) == (out / name).read_bytes()
    finally:
        web.stop_server(server)
    with pytest.raises(urllib.error.URLError):
        get(url)


def test_server_takes_the_next_port_when_busy(baked):
    _, out = baked
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        server, url = web.start_server(out, port=busy)
        try:
            assert busy < server.server_address[1] < busy + web.PORT_TRIES
            assert get(url + "baked.json") == (out / "baked.json").read_bytes()
        finally:
            web.stop_server(server)


def test_page_is_written_when_missing_and_served_from_the_package_otherwise(baked, tmp_path):
    _, out = baked
    scene = tmp_path / "copy"
    scene.mkdir()
    for name in ("baked.json", "index.npy", "density.npy", "sh.npy"):
        shutil.copy(out / name, scene / name)
    server, url = web.start_server(scene, write_page=False)  # the folder stays untouched
    try:
        assert not (scene / "index.html").exists()
        assert get(url) == (web.WEB_DIR / "index.html").read_bytes()
    finally:
        web.stop_server(server)
    server, _ = web.start_server(scene)
    web.stop_server(server)
    assert (scene / "index.html").read_bytes() == (web.WEB_DIR / "index.html").read_bytes()
    for name in web.ASSETS:
        assert (scene / name).read_bytes() == (web.WEB_DIR / name).read_bytes()


def test_serve_baked_prints_the_address_and_stops_on_ctrl_c(baked, monkeypatch, capsys):
    _, out = baked

    def interrupt(seconds):
        raise KeyboardInterrupt

    monkeypatch.setattr(web.time, "sleep", interrupt)
    web.serve_baked(out, host="localhost", port=0)  # returns normally
    text = capsys.readouterr().out
    assert "http://localhost:" in text and " MB" in text and "warning" not in text
    url = re.search(r"http://\S+", text).group(0)
    with pytest.raises(urllib.error.URLError):
        get(url)
    assert web.is_loopback("127.0.0.1") and web.is_loopback("localhost") and web.is_loopback("::1")
    assert not web.is_loopback("0.0.0.0") and not web.is_loopback("192.168.1.2")


@pytest.mark.parametrize("case", ["missing", "empty", "foreign", "no arrays"])
def test_bad_folders_are_one_line_config_errors(tmp_path, case):
    folder = tmp_path / "scene"
    if case != "missing":
        folder.mkdir()
    if case == "foreign":
        (folder / "baked.json").write_text(json.dumps({"format": "something-else"}))
    if case == "no arrays":
        (folder / "baked.json").write_text(json.dumps({"format": FORMAT}))
    with pytest.raises(ConfigError) as e:
        web.start_server(folder)
    msg = str(e.value)
    assert str(folder) in msg and "nerfkit bake" in msg and len(msg.splitlines()) == 1


def test_view_baked_not_a_folder_through_the_cli(tmp_path, capsys):
    assert main(["view", "--baked", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip()
    assert "nerfkit bake" in err and len(err.splitlines()) == 1, err
