"""A real browser opens a generated run report from disk: every image and video loads.

Headless Chromium (Debian package `chromium`; .ci/run installs it where missing) is driven
over the DevTools protocol on a pipe (--remote-debugging-pipe: JSON messages separated by
NUL bytes on file descriptors 3 and 4), so no extra Python package or network port is
needed. The page is opened as file://, exactly as a person would open it; after the load
event the test waits until every <video> has decoded its first frame (or failed), reads
back the state of every <img> and <video>, and saves a full-page screenshot.
"""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
from chromium import Chromium
from html_refs import local_refs

from nerfkit.core.presets import preset
from nerfkit.data.procedural.scene import make_scene
from nerfkit.evaluation.evaluate import evaluate_run, render_run
from nerfkit.report.run import write_report
from nerfkit.training.trainer import Trainer

# After load: wait (up to 30 s) until every video decoded a frame or failed, then report.
MEDIA_STATE_JS = """
(async () => {
  const videos = [...document.querySelectorAll('video')];
  const end = Date.now() + 30000;
  while (Date.now() < end && videos.some(v => v.readyState < 2 && !v.error)) {
    await new Promise(r => setTimeout(r, 100));
  }
  return {
    images: [...document.images].map(i => ({src: i.getAttribute('src'), complete: i.complete,
                                             width: i.naturalWidth, height: i.naturalHeight})),
    videos: videos.map(v => ({src: v.getAttribute('src'), readyState: v.readyState,
                              error: v.error ? v.error.code : null, width: v.videoWidth, height: v.videoHeight})),
    title: document.title,
    sections: [...document.querySelectorAll('section h2')].map(h => h.textContent),
  };
})()
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    scene = make_scene(root / "scene", size=24, n_train=6, n_val=2, n_test=2, seed=0)
    cfg = preset("tiny")
    cfg.train.max_steps, cfg.train.val_every, cfg.train.ckpt_every, cfg.train.log_every = 10, 5, 10, 2
    cfg.train.val_views = 2
    run = root / "run"
    Trainer(scene, run, cfg, progress=False).run()
    evaluate_run(run, scene, "test", progress=False)
    render_run(run, scene, orbit=4, progress=False)
    return write_report(run)


def test_report_links_are_relative_and_exist(report):
    refs = local_refs(report)
    assert refs
    missing = [str(p) for p in refs if not p.exists()]
    assert not missing, missing
    text = report.read_text()
    assert "sum" in text and "w<sub>i</sub> t<sub>i</sub>" in text  # how depth is computed
    for needle in ("train_loss.png", "val_psnr.png", "view_000.png", "eval_test.json", "rgb.mp4", "depth.mp4",
                   "config.json", "_depth.npy"):
        assert needle in text, needle
    assert "<script" not in text.lower() and "http://" not in text and "https://" not in text


def test_report_opens_in_headless_chromium(chromium, report, tmp_path):  # chromium first: skip before building
    browser = Chromium(chromium, tmp_path / "profile")
    try:
        browser.open_page()
        browser.navigate(report.resolve().as_uri())
        state = browser.evaluate(MEDIA_STATE_JS, timeout=60)
        shot = tmp_path / "report.png"
        browser.screenshot(shot)
    finally:
        browser.close()

    assert state["title"].startswith("nerfkit run")
    assert {"Curves", "Validation images", "Evaluation", "Videos", "Depth", "Config"} <= set(state["sections"])
    assert len(state["images"]) >= 8, state["images"]
    broken = [i for i in state["images"] if not (i["complete"] and i["width"] > 0 and i["height"] > 0)]
    assert not broken, f"images that did not load: {broken}"
    assert len(state["videos"]) == 2, state["videos"]  # the orbit's rgb.mp4 and depth.mp4
    bad = [v for v in state["videos"] if v["error"] is not None or v["readyState"] < 2 or v["width"] <= 0]
    assert not bad, f"videos that did not load or decode: {bad}"

    # The screenshot is a real, non-blank PNG of the whole page.
    import imageio.v3 as iio

    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = iio.imread(shot)
    assert img.shape[1] >= 800 and img.shape[0] >= 1000, img.shape
    assert float(np.std(img[..., :3])) > 10, "screenshot is blank"
    keep = os.environ.get("NERFKIT_REPORT_SCREENSHOT")
    if keep:  # for a person to look at: NERFKIT_REPORT_SCREENSHOT=/tmp/report.png pytest ...
        shutil.copy(shot, keep)
