"""What the web-renderer tests share: a loopback page in headless Chromium that draws splat files
(tests/spark_splats.py: Spark; tests/playcanvas_splats.py: the PlayCanvas engine), the pose and field of view
nerfkit's cameras give a web renderer, and the screenshots the tests keep.

How: a loopback HTTP server (http.server in a thread on 127.0.0.1, a free port) serves a page (at / and
/index.html), tests/web's node_modules (/node_modules/...) and the files registered (/files/NAME), nothing else,
so nothing reaches the network. WebPage starts it, starts Chromium (tests/chromium.py, WebGL2 on SwiftShader) with
a window of the size asked (at least 64 x 64), loads the page and waits until its `ready_expression` is true (its
modules loaded). Each page begins with HEAD, which collects window.onerror and unhandled rejections in
window.__errors; with console.* and Runtime.exceptionThrown they go into the RuntimeError of a failure
(WebPage.errors). A subclass's render calls its page's render function through WebPage._draw, which reads back
the canvas as a PNG data URL (lossless).

Camera: a web renderer's perspective camera takes a vertical field of view (fov_y: 2 atan(H / 2 fy)) and an
aspect W / H, so it draws a nerfkit pinhole Camera only with fx = fy and a centred principal point (anything else
is refused); its camera-to-world is OpenGL's, as nerfkit's (looking down -z, +y up).
"""

from __future__ import annotations

import base64
import functools
import http.server
import io
import json
import os
import shutil
import threading
import time
from pathlib import Path

import numpy as np
from chromium import Chromium
from web_tools import WEB

from nerfkit.rays.cameras import Camera

F = np.diag([1.0, -1.0, -1.0, 1.0])  # 180 degrees about x: the capture's axes (RDF) <-> SPZ's and glTF's (RUB)

# The start of every page (WebPage.errors reads window.__errors); html_page() puts a renderer's scripts after it.
HEAD = """<!doctype html>
<html><head><meta charset="utf-8"><style>html, body { margin: 0; background: #808080; }
canvas { display: block; }</style>
<script>window.__errors = [];
window.addEventListener("error", e => window.__errors.push("error: " + (e.message || e) + " at " + e.filename
  + ":" + e.lineno));
window.addEventListener("unhandledrejection", e => window.__errors.push("unhandled rejection: "
  + ((e.reason && (e.reason.stack || e.reason.message)) || e.reason)));</script>
"""


def html_page(scripts: str) -> str:
    """A page: HEAD, then `scripts` (a renderer's <script> elements), in an empty body's document."""
    return HEAD + scripts + "</head><body></body></html>\n"


class Handler(http.server.SimpleHTTPRequestHandler):
    """Serves / (the page), /node_modules/... (tests/web's) and /files/NAME (the files registered); nothing else.
    functools.partial(Handler, files=..., page=...) makes one for a server."""

    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript",
                      ".mjs": "text/javascript", ".wasm": "application/wasm"}

    def __init__(self, *args, files: dict, page: bytes, **kwargs):
        self.files = files
        self.page = page
        super().__init__(*args, directory=str(WEB), **kwargs)

    def translate_path(self, path):
        path = path.split("?", 1)[0].split("#", 1)[0]
        if path.startswith("/files/"):
            return str(self.files.get(path[len("/files/"):], "/nonexistent"))
        if path.startswith("/node_modules/"):
            return super().translate_path(path)
        return "/nonexistent"

    def do_GET(self):
        if self.path.split("?", 1)[0] in ("/", "/index.html"):
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(self.page)))
            self.end_headers()
            self.wfile.write(self.page)
            return
        super().do_GET()

    def log_message(self, *args):  # quiet
        pass


class WebPage:
    """One headless Chromium showing a page (page_html) served on the loopback, for several renders in a row; a
    context manager (close() ends the browser and the server). A subclass (SparkPage, PlayCanvasPage) gives the
    page and its render; `name`, the renderer's, is what messages call it."""

    name = "WebPage"

    def __init__(self, chromium: str, profile: Path, size: tuple[int, int], page_html: str, ready_expression: str):
        """Start the server and the browser (window `size` (w, h)) and load the page; RuntimeError with the page's
        errors when ready_expression (JavaScript) is not true within 60 s."""
        self.files: dict[str, Path] = {}  # URL name -> file
        self.server = http.server.ThreadingHTTPServer(
            ("127.0.0.1", 0), functools.partial(Handler, files=self.files, page=page_html.encode()))
        self.server.daemon_threads = True
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        self.browser = None
        self.last = {}  # what the last render said besides its image (frames, ...)
        try:
            self.browser = Chromium(chromium, profile, max(int(size[0]), 64), max(int(size[1]), 64), webgl=True)
            self.browser.open_page()
            self.browser.navigate(f"http://127.0.0.1:{self.server.server_address[1]}/")
            t0 = time.time()
            while not self.browser.evaluate(ready_expression):
                if time.time() - t0 > 60:
                    raise RuntimeError(f"the {self.name} page did not load its modules within 60 s: {self.errors()}")
                time.sleep(0.1)
        except BaseException:
            self.close()
            raise

    def errors(self) -> list[str]:
        """The page's errors and console messages so far, for a failure's message."""
        out = []
        if self.browser is None:
            return out
        for m in self.browser.events:
            if m.get("method") == "Runtime.consoleAPICalled":
                p = m["params"]
                out.append(f"console.{p['type']}: " + " ".join(str(a.get("value", a.get("description", "")))
                                                                for a in p.get("args", [])))
            elif m.get("method") == "Runtime.exceptionThrown":
                d = m["params"]["exceptionDetails"]
                out.append("exception: " + str(d.get("exception", {}).get("description", d.get("text"))))
        try:
            out += self.browser.evaluate("window.__errors || []", timeout=10) or []
        except Exception as e:  # noqa: BLE001 - a page that cannot answer says so in the message
            out.append(f"(the page did not answer: {e})")
        return out

    def _url(self, file: Path) -> str:
        """The URL the page fetches `file` at (registered once): /files/N.EXT, the extension kept, lower case
        (Spark tells the format by extension and content; PlayCanvas's container handler .glb from .gltf by
        name)."""
        file = Path(file).resolve()
        for name, known in self.files.items():
            if known == file:
                return f"/files/{name}"
        name = f"{len(self.files)}{file.suffix.lower()}"
        self.files[name] = file
        return f"/files/{name}"

    def _draw(self, function: str, file: Path, args: dict, timeout: float) -> np.ndarray:
        """[H, W, 3] in [0, 1]: awaits window.FUNCTION(args) on the page (args["w"] x args["h"] pixels, at most
        args["maxFrames"] renders), which answers {png: the canvas as a PNG data URL, settled, ...}; the rest of its
        answer goes into self.last. RuntimeError, with the page's errors, when it fails or does not settle."""
        import imageio.v3 as iio

        try:
            got = self.browser.evaluate(f"window.{function}({json.dumps(args)})", timeout=timeout)
        except Exception as e:  # noqa: BLE001 - said again with the page's errors
            raise RuntimeError(f"{self.name} failed to render {file.name}: {e}; page: {self.errors()}") from None
        if not got or not got.get("settled"):
            raise RuntimeError(f"{self.name}'s renders of {file.name} did not settle within {args['maxFrames']} "
                               f"frames ({got and {k: v for k, v in got.items() if k != 'png'}}); page: "
                               f"{self.errors()}")
        self.last = {k: v for k, v in got.items() if k != "png"}
        img = iio.imread(io.BytesIO(base64.b64decode(got["png"].split(",", 1)[1])))
        w, h = args["w"], args["h"]
        if img.shape[:2] != (h, w):
            raise RuntimeError(f"{self.name}'s canvas read back {img.shape[1]} x {img.shape[0]}, not {w} x {h}")
        return img[..., :3].astype(np.float32) / 255.0

    def close(self) -> None:
        if self.browser is not None:
            self.browser.close()
            self.browser = None
        self.server.shutdown()
        self.server.server_close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def fov_y(camera: Camera) -> float:
    """three.js's (and PlayCanvas's) vertical field of view (degrees) of a nerfkit pinhole Camera; ValueError unless
    fx = fy and the principal point is the image's centre (what a PerspectiveCamera draws)."""
    w, h = int(camera.width), int(camera.height)
    if camera.params or abs(camera.fx - camera.fy) > 1e-6 * camera.fy or abs(camera.cx - 0.5 * w) > 1e-6 * w \
            or abs(camera.cy - 0.5 * h) > 1e-6 * h:
        raise ValueError(f"a PerspectiveCamera draws a pinhole with fx = fy and a centred principal point, not "
                         f"{camera}")
    return float(np.degrees(2 * np.arctan(0.5 * h / camera.fy)))


def training_view(run: Path, index: int = 0, size: int | None = None) -> tuple[np.ndarray, Camera]:
    """(camera-to-world [4, 4] in the capture's coordinates, pinhole Camera) of training view `index` of a run
    (its scene.json: train_poses in the run's normalised frame, undone by transform and scale as
    evaluation/evaluate.capture_poses does; the camera's fy, centred, fx = fy). size: the longer side in pixels,
    the field of view kept (None: the run's own size)."""
    sc = json.loads((Path(run) / "scene.json").read_text())
    base = Camera.from_json(sc["camera"])
    pose = np.asarray(sc["train_poses"][index], np.float64)
    c2w = np.linalg.inv(np.asarray(sc["transform"], np.float64)) @ pose @ np.diag([float(sc["scale"])] * 3 + [1.0])
    rot = c2w[:3, :3]
    if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-4):
        raise ValueError(f"{run}: training view {index} is not a rotation in the capture's coordinates")
    s = 1.0 if size is None else size / max(base.width, base.height)
    w, h = round(base.width * s), round(base.height * s)
    return c2w, Camera.pinhole(w, h, base.fy * h / base.height)


def keep(png: Path, env_var: str) -> None:
    """Copy a comparison (a screenshot) into the folder $ENV_VAR names, when set."""
    folder = os.environ.get(env_var)
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        shutil.copy(png, Path(folder) / png.name)
