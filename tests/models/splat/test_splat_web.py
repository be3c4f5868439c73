"""`nerfkit bake` of a splat run: the static WebGL2 page, in headless Chromium (software WebGL2), draws what
nerfkit's tile rasteriser renders.

The page sorts the Gaussians by view depth and blends them back to front in an 8-bit framebuffer;
the rasteriser blends front to back in float32 and stops at T < 1e-4. Both project, cut and
weigh each Gaussian by the same rules (splat/web/splat.js), so they differ by 8-bit rounding of
every blend and by the sort (per Gaussian, the same z-depth key). A screenshot is kept
(NERFKIT_SPLAT_SCREENSHOT=/path.png copies it out).
"""

from __future__ import annotations

import base64
import json
import os
import shutil

import numpy as np
import pytest
from chromium import Chromium

from nerfkit.bake import web
from nerfkit.cli.main import main
from nerfkit.core.metrics import psnr
from nerfkit.data.loader import load_scene
from nerfkit.models.splat.gaussians import render_frame
from nerfkit.rays.cameras import Camera
from nerfkit.render.images import make_renderer
from nerfkit.run.folder import RunFolder

SIZE = 64


@pytest.fixture(scope="module")
def baked(splat_run, tmp_path_factory):
    scene, run = splat_run
    page = tmp_path_factory.mktemp("splatweb") / "page"
    assert main(["bake", str(run), "--out", str(page), "--no-progress"]) == 0
    return scene, run, page


def test_bake_refuses_the_field_flags_and_replaces_only_with_overwrite(baked, tmp_path, capsys):
    _, run, page = baked
    assert main(["bake", str(run), "--out", str(tmp_path / "p"), "--sh-bands", "3"]) == 1
    assert "--sh-bands" in capsys.readouterr().err and not (tmp_path / "p").exists()
    assert main(["bake", str(run), "--out", str(page)]) == 1
    assert "--overwrite" in capsys.readouterr().err
    meta = json.loads((page / "splats.json").read_text())
    assert (page / "splats.bin").stat().st_size == meta["count"] * 64 * 4


def test_page_draws_what_the_rasteriser_renders(chromium, baked, tmp_path):
    scene, run, page = baked
    run_ = RunFolder(run).load()
    cfg, model, params, aux = run_.cfg, run_.model, run_.params, run_.aux
    ref = make_renderer(model)
    test = load_scene(scene, "test")
    server, url = web.start_server(page)
    browser = Chromium(chromium, tmp_path / "profile", 640, 480, webgl=True)
    scores = []
    try:
        browser.open_page()
        browser.navigate(url)
        info = browser.evaluate("window.nerfkitSplat.ready", timeout=120)
        assert info["count"] == int(np.asarray(aux["active"]).sum())
        for k in range(len(test)):
            cam = Camera.pinhole(SIZE, SIZE, test.cameras[k].fx * SIZE / test.cameras[k].width)
            want = ref.render_camera(params, aux, test.poses[k], cam)["rgb"]
            arg = json.dumps({"c2w": np.asarray(test.poses[k], float).tolist(), "width": SIZE, "height": SIZE,
                              "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy})
            px = base64.b64decode(browser.evaluate(f"window.nerfkitSplat.render({arg})", timeout=120))
            got = np.frombuffer(px, np.uint8).reshape(SIZE, SIZE, 4)
            scores.append(float(psnr(got[..., :3].astype(np.float32) / 255.0, want)))
        ms = browser.evaluate("window.nerfkitSplat.draw()", timeout=120)
        assert ms > 0
        errors = [e for e in browser.events if e.get("method") == "Runtime.exceptionThrown"]
        assert not errors, errors
        shot = tmp_path / "splat_web.png"
        browser.screenshot(shot)
    finally:
        browser.close()
        web.stop_server(server)
    print("page vs rasteriser PSNR (dB):", ", ".join(f"{s:.2f}" for s in scores))
    assert min(scores) >= 35.0, scores  # measured 51.9 and 52.7 dB (the shared 200-step run; 39.7 and 40.9 after 30 steps)
    keep = os.environ.get("NERFKIT_SPLAT_SCREENSHOT")
    if keep:
        shutil.copy(shot, keep)


def test_page_draws_with_the_runs_screen_dilation(chromium, baked, tmp_path):
    """splats.json's "dilation" (the run's --screen-dilation) reaches the shader: a page whose value is 3 px^2
    draws what the rasteriser draws at 3, far from its drawing at 0.3."""
    scene, run, page = baked
    wide = tmp_path / "wide"
    shutil.copytree(page, wide)
    meta = json.loads((wide / "splats.json").read_text())
    assert meta["dilation"] == 0.3  # the run's setting, written by the bake
    (wide / "splats.json").write_text(json.dumps({**meta, "dilation": 3.0}))
    run_ = RunFolder(run).load()
    _, on_device = make_renderer(run_.model).gaussians(run_.params, run_.aux)
    test = load_scene(scene, "test")
    cam = Camera.pinhole(SIZE, SIZE, test.cameras[0].fx * SIZE / test.cameras[0].width)
    want = {d: render_frame(on_device, test.poses[0], cam, run_.model.background, run_.cfg.splat.sh_degree,
                            dilation=d)["rgb"] for d in (0.3, 3.0)}
    server, url = web.start_server(wide)
    browser = Chromium(chromium, tmp_path / "profile", 640, 480, webgl=True)
    try:
        browser.open_page()
        browser.navigate(url)
        browser.evaluate("window.nerfkitSplat.ready", timeout=120)
        arg = json.dumps({"c2w": np.asarray(test.poses[0], float).tolist(), "width": SIZE, "height": SIZE,
                          "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy})
        px = base64.b64decode(browser.evaluate(f"window.nerfkitSplat.render({arg})", timeout=120))
    finally:
        browser.close()
        web.stop_server(server)
    got = np.frombuffer(px, np.uint8).reshape(SIZE, SIZE, 4)[..., :3].astype(np.float32) / 255.0
    at3, at03 = psnr(got, want[3.0]), psnr(got, want[0.3])
    print(f"page at 3 px^2 vs rasteriser at 3: {at3:.2f} dB, at 0.3: {at03:.2f} dB")
    assert at3 >= 35.0 and at3 > at03 + 5.0, (at3, at03)
