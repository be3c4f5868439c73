"""A real browser opens a generated run report from disk: every image and video loads.

Headless Chromium (Debian package `chromium`; .ci/run installs it where missing) is driven
over the DevTools protocol on a pipe (--remote-debugging-pipe: JSON messages separated by
NUL bytes on file descriptors 3 and 4), so no extra Python package or network port is
needed. The page is opened as file://, exactly as a person would open it; after the load
event the test waits until every <video> has decoded its first frame (or failed), reads
back the state of every <img> and <video>, and saves a full-page screenshot.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest

from nerfkit.config import preset
from nerfkit.data.scene import make_scene
from nerfkit.evaluate import evaluate_run, render_run
from nerfkit.report import write_report
from nerfkit.train import Trainer

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    env = os.environ.get("NERFKIT_CHROMIUM")
    if env:
        return env if os.access(env, os.X_OK) else None
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


# Put the two pipe ends on fds 3 and 4, then become the browser (a tiny trampoline: the
# shell cannot name fds above 9 portably, and preexec_fn is unsafe in a threaded process).
_EXEC_WITH_PIPES = "import os, sys; os.dup2(int(sys.argv[1]), 3); os.dup2(int(sys.argv[2]), 4); " \
                   "os.execv(sys.argv[3], sys.argv[3:])"


class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe (stdlib only)."""

    def __init__(self, binary: str, profile: Path, width: int = 1280, height: int = 900):
        to_chrome_r, to_chrome_w = os.pipe()
        from_chrome_r, from_chrome_w = os.pipe()
        # Chromium reads commands on fd 3 and writes replies on fd 4. Move our pipe ends
        # above 10 first so that placing them on 3 and 4 can never clobber one with the other.
        hi_r = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD, 10)
        hi_w = fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD, 10)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        args = [binary, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--no-first-run", "--no-default-browser-check", "--mute-audio", "--hide-scrollbars",
                "--autoplay-policy=no-user-gesture-required",
                f"--user-data-dir={profile}", f"--window-size={width},{height}", "--remote-debugging-pipe",
                "about:blank"]
        self.proc = subprocess.Popen([sys.executable, "-c", _EXEC_WITH_PIPES, str(hi_r), str(hi_w), *args],
                                     pass_fds=(hi_r, hi_w), stdin=subprocess.DEVNULL,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        os.close(hi_r)
        os.close(hi_w)
        self.w, self.r = to_chrome_w, from_chrome_r
        self.buf = b""
        self.next_id = 0
        self.events: list[dict] = []
        self.session: str | None = None

    def _read_message(self, deadline: float) -> dict:
        while b"\0" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no answer from chromium")
            ready, _, _ = select.select([self.r], [], [], left)
            if ready:
                chunk = os.read(self.r, 1 << 20)
                if not chunk:
                    err = self.proc.stderr.read().decode(errors="replace") if self.proc.poll() is not None else ""
                    raise RuntimeError(f"chromium closed the DevTools pipe (exit {self.proc.poll()}): {err[-2000:]}")
                self.buf += chunk
        msg, self.buf = self.buf.split(b"\0", 1)
        return json.loads(msg)

    def send(self, method: str, params: dict | None = None, session: bool = True, timeout: float = 60) -> dict:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            m = self._read_message(deadline)
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def wait_event(self, method: str, timeout: float = 60) -> dict:
        deadline = time.monotonic() + timeout
        for k, m in enumerate(self.events):
            if m.get("method") == method:
                return self.events.pop(k)
        while True:
            m = self._read_message(deadline)
            if m.get("method") == method:
                return m
            self.events.append(m)

    def open_page(self) -> None:
        target = self.send("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
        self.session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True},
                                 session=False)["sessionId"]
        self.send("Page.enable")
        self.send("Runtime.enable")

    def navigate(self, url: str, timeout: float = 60) -> None:
        self.events.clear()
        self.send("Page.navigate", {"url": url})
        self.wait_event("Page.loadEventFired", timeout)

    def evaluate(self, expression: str, timeout: float = 60):
        res = self.send("Runtime.evaluate", {"expression": expression, "awaitPromise": True,
                                             "returnByValue": True}, timeout=timeout)
        if "exceptionDetails" in res:
            raise RuntimeError(f"page script failed: {res['exceptionDetails']}")
        return res["result"].get("value")

    def screenshot(self, path: Path) -> None:
        size = self.send("Page.getLayoutMetrics")["cssContentSize"]
        clip = {"x": 0, "y": 0, "width": size["width"], "height": min(size["height"], 12000), "scale": 1}
        data = self.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True, "clip": clip})
        path.write_bytes(base64.b64decode(data["data"]))

    def close(self) -> None:
        try:
            self.send("Browser.close", session=False, timeout=10)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self.w)
        os.close(self.r)


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


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs: list[str] = []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("src", "href") and v:
                self.refs.append(v)


def local_refs(report: Path) -> list[Path]:
    """Every src/href of the page, as files; fails on absolute or network links."""
    p = _Refs()
    p.feed(report.read_text())
    out = []
    for ref in p.refs:
        if ref.startswith("#"):
            continue
        u = urlparse(ref)
        assert not u.scheme and not u.netloc and not ref.startswith("/"), f"not a relative link: {ref}"
        out.append((report.parent / unquote(u.path)).resolve())
    return out


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


@pytest.fixture
def chromium():
    binary = find_chromium()
    if binary is None:
        pytest.skip("no Chromium found (looked for " + ", ".join(CHROMIUM_NAMES) + " and $NERFKIT_CHROMIUM); "
                    "install the Debian package: apt-get install chromium (.ci/run does this)")
    return binary


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
