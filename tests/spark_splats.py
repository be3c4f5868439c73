"""Spark (World Labs' three.js Gaussian splat renderer, npm @sparkjsdev/spark 2.2.0 with three 0.187.0, pinned in
tests/web) drawing a splat file in headless Chromium, as a web page that embeds it would: shared by
tests/models/splat/formats/test_spark.py and the benchmarks (spark_vs_nerfkit, training_view).

How: a WebPage (tests/splat_pages.py: a loopback server, nothing from the network; headless Chromium; the
page's errors) serves a small page whose import map points "three" (and "three/addons/", which Spark imports) and
"@sparkjsdev/spark" at their module builds in tests/web's node_modules. The page makes a THREE.WebGLRenderer (no
antialiasing, preserveDrawingBuffer, pixel ratio 1, a canvas of exactly W x H), a SparkRenderer added to the
scene, and a SplatMesh({url}) left at the identity (no turn: nothing a user's page adds by itself), awaits the
mesh's `initialized`, sets the camera and renders, one frame per requestAnimationFrame, until Spark's worker has
sorted for that camera (!sorting, !sortDirty, activeSplats > 0) and three readbacks in a row (canvas.toDataURL,
PNG: lossless) agree: the first frames draw nothing, or an older order. Page errors (window.onerror, unhandled
rejections, console.*, Runtime.exceptionThrown) go into the RuntimeError of a failure.

Camera: a three.js PerspectiveCamera whose camera-to-world is the pose given (nerfkit's convention and three.js's
agree: OpenGL, looking down -z, +y up), vertical field of view 2 atan(H / 2 fy), aspect W / H, near 0.01, far
1000, for a nerfkit pinhole Camera with fx = fy and a centred principal point (anything else is refused); the
background is white, as nerfkit's renders.

Spark's own choices, and what the page sets by default so that it draws Gaussians as nerfkit's rasteriser does
(NERFKIT_MATCH; `options` overrides them, {} gives Spark's defaults):

    blurAmount 0.3 (default): 0.3 px^2 added to the 2D covariance WITH opacity compensation (Mip-Splatting's
        filter); nerfkit adds 0.3 px^2 without it (project.py, 3DGS's dilation), which is Spark's preBlurAmount:
        preBlurAmount 0.3, blurAmount 0. Spark's default dims Gaussians about a pixel wide: on the shared
        200-step run (trained at 32 px) its defaults score 22.7-24.1 dB against nerfkit at 32 px, 45.1-46.3 dB at
        192 px; NERFKIT_MATCH 50.6-52.5 and 49.4-51.3 dB.
    maxStdDev sqrt(8) (default): nerfkit cuts at 3 sigma: 3.
    sortRadial true (default): nerfkit sorts by z-depth: false.

Spark also quantises what it draws (PackedSplats' default encoding: base colour 8 bits clipped to [0, 1], SH
coefficients 6 to 8 bits over [-1, 1]), so strongly view-dependent Gaussians score 36.6-39.9 dB, not ~50.

Axes, found by measurement (test_spark.py; the same Gaussians as .ply, .spz and .splat, each drawn with the pose
as given and turned by F): Spark converts NO format's axes: it draws the coordinates stored in the file (its own
README turns its example .spz by 180 degrees about x, on the mesh, by hand). nerfkit writes .ply and .splat in the
capture's coordinates and .spz (and .glb) in RUB, the capture's turned by F = diag(1, -1, -1) (formats/spz.py),
so the capture seen from c2w is, in a .spz, seen from F @ c2w. AXIS_RULE says so per extension and render()
applies it unless told `flip`. Shared run, 192 px, training views 0, 3, 6: .ply and .splat with the pose as given
49.4-51.3 dB, turned 11.2-12.7 dB; .spz as given 11.2-12.6 dB, turned (F @ c2w) 50.9-51.3 dB.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from splat_pages import F, WebPage, fov_y, html_page, training_view

from nerfkit.rays.cameras import Camera

# F, fov_y and training_view live in splat_pages; the benchmarks and tests import them from here too.
__all__ = ["AXIS_RULE", "F", "MODULES", "NERFKIT_MATCH", "PAGE", "SparkPage", "fov_y", "spark_render",
           "spark_vs_nerfkit", "training_view"]

# The pose Spark must take, in the file's own coordinates, to show the capture as a camera c2w in the capture's
# coordinates sees it: AXIS_RULE[extension] @ c2w (nerfkit writes .spz and .glb turned by F; Spark draws as stored).
AXIS_RULE = {".ply": np.eye(4), ".splat": np.eye(4), ".spz": F, ".glb": F, ".gltf": F}

# SparkRenderer options that make Spark draw as nerfkit's rasteriser (the module docstring says why).
NERFKIT_MATCH = {"preBlurAmount": 0.3, "blurAmount": 0.0, "maxStdDev": 3.0, "sortRadial": False}

MODULES = {"three": "/node_modules/three/build/three.module.js",
           "three/addons/": "/node_modules/three/examples/jsm/",  # Spark imports three/addons/postprocessing/
           "@sparkjsdev/spark": "/node_modules/@sparkjsdev/spark/dist/spark.module.js"}

PAGE = html_page("""<script type="importmap">{"imports": IMPORTS}</script>
<script type="module">
import * as THREE from "three";
import { SparkRenderer, SplatMesh } from "@sparkjsdev/spark";

const frame = () => new Promise(r => requestAnimationFrame(() => r()));
const meshes = new Map();
let renderer = null, scene = null, spark = null, sparkKey = null, shown = null;

async function mesh(url) {
  if (!meshes.has(url)) {
    const m = new SplatMesh({ url });
    await m.initialized;
    meshes.set(url, m);
  }
  return meshes.get(url);
}

// Render the file at `url` from camera-to-world c2w (16 numbers, column-major) with vertical field of view fov
// (degrees) on a w x h canvas, SparkRenderer options `options`: {png: the canvas as a PNG data URL, frames: how
// many renders it took, settled: whether Spark had sorted and three readbacks in a row agreed, splats}.
window.sparkRender = async ({ url, c2w, fov, w, h, options, minFrames, maxFrames }) => {
  if (renderer === null) {
    renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
    renderer.setPixelRatio(1);
    document.body.appendChild(renderer.domElement);
    scene = new THREE.Scene();
    scene.background = new THREE.Color(1, 1, 1);
  }
  const key = JSON.stringify(options);
  if (sparkKey !== key) {
    if (spark !== null) { scene.remove(spark); if (spark.dispose) spark.dispose(); }
    spark = new SparkRenderer({ renderer, ...options });
    scene.add(spark);
    sparkKey = key;
  }
  renderer.setSize(w, h);  // the canvas: w x h CSS pixels, and (pixel ratio 1) its drawing buffer
  const m = await mesh(url);
  if (shown !== m) { if (shown !== null) scene.remove(shown); scene.add(m); shown = m; }
  const camera = new THREE.PerspectiveCamera(fov, w / h, 0.01, 1000);
  new THREE.Matrix4().fromArray(c2w).decompose(camera.position, camera.quaternion, camera.scale);
  camera.updateMatrixWorld(true);
  let prev = null, same = 0;
  for (let k = 1; k <= maxFrames; k++) {
    renderer.render(scene, camera);
    const png = renderer.domElement.toDataURL("image/png");
    // Spark generates and sorts in a worker: a readback counts once the sort it drew is this camera's
    const ready = !spark.sorting && !spark.sortDirty && spark.activeSplats > 0;
    same = ready && png === prev ? same + 1 : 0;
    if (k >= minFrames && same >= 2) return { png, frames: k, settled: true, splats: spark.activeSplats };
    prev = ready ? png : null;
    await frame();
  }
  return { png: prev, frames: maxFrames, settled: false, splats: spark.activeSplats };
};
window.sparkReady = true;
</script>""").replace("IMPORTS", json.dumps(MODULES))


class SparkPage(WebPage):
    """One headless Chromium showing the Spark page, for several renders (files, poses, options) in a row; a
    context manager (close() ends the browser and the server)."""

    name = "Spark"

    def __init__(self, chromium: str, profile: Path, size: tuple[int, int] = (400, 400)):
        """Start the server and the browser (window `size` (w, h)) and load the page; RuntimeError with the page's
        errors when its modules do not load within 60 s."""
        super().__init__(chromium, profile, size, PAGE, "window.sparkReady === true")

    def render(self, file: Path, c2w: np.ndarray, camera: Camera, flip: np.ndarray | None = None,
               options: dict | None = None, min_frames: int = 3, max_frames: int = 100) -> np.ndarray:
        """Spark's render [H, W, 3] in [0, 1] of `file` seen from c2w [4, 4] (OpenGL camera-to-world in the
        capture's coordinates) through the pinhole `camera` (fov_y). Spark's camera is flip @ c2w, in the file's
        own coordinates: flip None takes AXIS_RULE by the file's extension; np.eye(4) the pose as given.
        options: SparkRenderer options (None: NERFKIT_MATCH; {}: Spark's defaults). self.last says how many
        renders it took. RuntimeError, with the page's errors, when Spark fails or its renders do not settle
        within max_frames."""
        file = Path(file)
        if flip is None:
            flip = AXIS_RULE[file.suffix.lower()]
        pose = np.asarray(flip, np.float64) @ np.asarray(c2w, np.float64)
        w, h = int(camera.width), int(camera.height)
        args = {"url": self._url(file), "c2w": pose.T.reshape(-1).tolist(), "fov": fov_y(camera), "w": w, "h": h,
                "options": NERFKIT_MATCH if options is None else options, "minFrames": int(min_frames),
                "maxFrames": int(max_frames)}
        return self._draw("sparkRender", file, args, timeout=120)


def spark_render(chromium: str, profile: Path, file: Path, c2w: np.ndarray, camera: Camera,
                 flip: np.ndarray | None = None, options: dict | None = None) -> np.ndarray:
    """Spark's render [H, W, 3] in [0, 1] of one splat file from one camera, in a browser of its own
    (SparkPage.render says what the arguments mean)."""
    with SparkPage(chromium, profile, (int(camera.width), int(camera.height))) as page:
        return page.render(file, c2w, camera, flip, options)


def spark_vs_nerfkit(page: SparkPage, file: Path, c2w: np.ndarray, camera: Camera, png: Path | None = None,
                     flip: np.ndarray | None = None, options: dict | None = None) -> dict:
    """{"psnr": dB, "spark": image, "nerfkit": image, "frames": Spark's renders} of Spark's render of a splat
    file (page.render with flip, options) against nerfkit's render of the same file as nerfkit reads it back
    (formats.read_gaussians: capture coordinates, the file's SH degree), clipped to [0, 1], from the same camera
    (c2w in the capture's coordinates). png: where to write the two side by side (nerfkit left, Spark right)."""
    from nerfkit.core.metrics import psnr
    from nerfkit.models.splat.formats import read_gaussians
    from nerfkit.models.splat.gaussians import render

    g, degree, _ = read_gaussians(file)
    want = np.clip(render(g, c2w, camera, sh_degree=degree, depth=False)["rgb"], 0.0, 1.0)
    got = page.render(file, c2w, camera, flip, options)
    if png is not None:
        import imageio.v3 as iio

        iio.imwrite(png, np.round(np.concatenate([want, got], 1) * 255).astype(np.uint8))
    return {"psnr": float(psnr(got, want)), "spark": got, "nerfkit": want, "frames": page.last.get("frames")}
