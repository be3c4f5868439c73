"""The PlayCanvas engine (npm playcanvas 2.23.3, pinned in tests/web) drawing a glTF file with
KHR_gaussian_splatting or a .sog in headless Chromium, as a web page that embeds it would: shared by
tests/models/splat/formats/test_playcanvas.py (playcanvas_vs_nerfkit).

How: a WebPage (tests/splat_pages.py: tests/web's node_modules and the registered files on 127.0.0.1, nothing
from the network; headless Chromium; the page's errors) serves a page which imports the engine's single module build
(build/playcanvas.min.mjs). It makes a pc.Application on a W x H canvas (WebGL2, no antialiasing,
preserveDrawingBuffer; FILLMODE_NONE, RESOLUTION_FIXED), a camera entity (clear colour white, as nerfkit's renders)
and, per file, a 'container' asset whose resource's instantiateRenderEntity() is added to the root at the identity:
the engine's own glTF loader (framework/parsers/glb/extensions/khr-gaussian-splatting.js, registered by the gsplat
component system) turns the primitive into a gsplat component, nothing a user's page adds by itself; a .sog is a
'gsplat' asset (the engine's SogBundleParser) shown by an entity with a gsplat component, as PlayCanvas's own
examples load one. The page
renders on demand (autoRender off, renderNextFrame per requestAnimationFrame) until the engine's sort worker has
answered for this camera (the scene's "gsplat:sorted" event, counted since the pose, the file or the work-buffer
format last changed: nothing else makes it sort again) and three readbacks in a row (canvas.toDataURL, PNG:
lossless) agree: the first frames draw nothing or an older order. Page errors (window.onerror, unhandled rejections,
console.*, Runtime.exceptionThrown) go into the RuntimeError of a failure.

Camera: the entity's world transform is the pose given (PlayCanvas's camera and nerfkit's c2w are both OpenGL:
looking down -z, +y up), fov the vertical field of view 2 atan(H / 2 fy) (splat_pages.fov_y: fx = fy and a
centred principal point, anything else refused), aspect W / H, near 0.01, far 1000. The .glb's world is the
capture's turned by F = diag(1, -1, -1) (formats/gltf.py: glTF is +Y up) and PlayCanvas draws glTF nodes as
stored, so the capture seen from c2w is, in the .glb, seen from F @ c2w: render() gives PlayCanvas F @ c2w unless
told `flip` (np.eye(4): the pose as given, the wrong convention for a .glb).

What PlayCanvas does, read from its source (build/playcanvas/src/scene/gsplat*, shader-lib/glsl/chunks/gsplat),
against nerfkit's rasteriser (project.py, reference.py):

    loader: reads POSITION, ROTATION (x y z w), SCALE and OPACITY as linear values (GSplatData.activated),
        SH_DEGREE_0_COEF_0 as 3DGS's f_dc (colour = 0.2820948 c + 0.5) and, when every attribute of a band is
        there, SH_DEGREE_1..3 as f_rest (bands 1-3, 3DGS's basis and order); kernel and colorSpace unread; COLOR_0
        unused. So it takes nerfkit's Gaussians as written, SH included.
    pipeline: since 2.x a gsplat component is "unified" by default: the Gaussians are first copied (once) into
        a work buffer, in GSPLATDATA_COMPACT by default: colour 11/11/10 bits over [0, 4], opacity 8 bits,
        log-scale 8 bits over [-12, 9] (steps of 8.6 % in scale), quaternion 11/11/10 bits; view-dependent colour
        is evaluated there, per Gaussian from the camera's centre (as nerfkit), SH coefficients stored at 11/10/11
        bits relative to each Gaussian's largest, and re-evaluated only once the camera has moved tan(10 deg) of
        its distance (colorUpdateAngle).
    footprint: 0.3 added to the 2D covariance, but one measured in half pixels (its focal length is
        viewport_size * projection[0][0] = 2 fx), so 0.075 px^2, a quarter of nerfkit's (3DGS's) 0.3 px^2, and
        without opacity compensation by default (antiAlias false); smaller eigenvalue floored at 0.025 px^2;
        Gaussians whose quad is under minPixelSize = 2 px across dropped.
    cutoff: the quad reaches sqrt(8) sigma and the kernel is renormalised to vanish there,
        alpha = o (e^{-d^2/2} - e^{-4}) / (1 - e^{-4}) with d the Mahalanobis distance (up to +1.9 % at the
        centre, 0 at sqrt 8); nerfkit uses o e^{-d^2/2} cut at 3 sigma. Fragments with alpha < 1/255 are
        discarded (nerfkit skips them too); no 0.99 clamp and no early stop at T < 1e-4 (nerfkit has both).
    sorting: back to front by z-depth along the camera's forward axis (radialSorting false), as nerfkit, but by
        a counting sort into 2^10 (small files) to 2^20 buckets, so near ties come out in index order.
    colour: the colours are taken as display (gamma) values and, with the camera's default linear tone mapping
        and sRGB gamma, go through pow 2.2 and back (identity), then are blended premultiplied into the 8-bit
        sRGB back buffer: nerfkit's compositing of display sRGB values on white, as the file's colorSpace
        srgb_rec709_display says.

Measured (SwiftShader WebGL2; test_playcanvas.py has the details and the floors), the shared test run's .glb at 192
px from training views 0, 3, 6: PlayCanvas's defaults against nerfkit 38.4-38.6 dB (PRECISE 38.6-39.0); at the run's
32 px 23.9-25.0. The footprint and the cutoff are the whole difference: playcanvas_model (nerfkit's projection with
PlayCanvas's 0.075 px^2 and renormalised sqrt(8)-sigma kernel) scores 51.4-51.6 dB against its defaults (PRECISE
56.5-56.8; 32 px: 49.9-51.7 and 53.4-54.7); with only one of the two (view 0, defaults): its kernel with nerfkit's
0.3 px^2 47.6 dB, nerfkit's kernel with its 0.075 px^2 40.6 dB. A turned pose (c2w instead of F @ c2w) 11.3-12.8 dB.
Gaussians with strong SH bands 1-3 (.glb or .gltf): 38.3 dB against nerfkit at degree 3, 21.0-21.9 at degree 0,
43.7-44.0 against playcanvas_model (PRECISE 44.8-45.1: the rest is, presumably, the SH's 11/10/11-bit packing).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from splat_pages import F, WebPage, fov_y, html_page

from nerfkit.rays.cameras import Camera

MODULE = "/node_modules/playcanvas/build/playcanvas.min.mjs"

# app.scene.gsplat settings that take out PlayCanvas's lossy steps (the module docstring says which): the LARGE
# work-buffer format (half floats) instead of COMPACT's 8-bit log scales, and no minimum splat size. Its kernel
# and dilation are in its shaders, not settings.
PRECISE = {"dataFormat": "large", "minPixelSize": 0}

# PlayCanvas's footprint (gsplatCorner): 0.3 added to a 2D covariance measured in half pixels (its focal length
# is viewport_size * projection[0][0] = 2 fx), i.e. 0.075 px^2; its kernel reaches sqrt(8) sigma (Mahalanobis^2 / 2
# <= 4) and is renormalised to vanish there (gsplatPS's normExp).
DILATION = 0.3 / 4.0
KERNEL_END = 4.0  # d^2 / 2 at the quad's edge, d = sqrt(8)
ALPHA_CLIP = 1.0 / 255.0  # alphaClipForward

PAGE = html_page("""<script type="module">
import * as pc from "MODULE";

const frame = () => new Promise(r => requestAnimationFrame(() => r()));
const entities = new Map();  // url -> the entity instantiateRenderEntity made
let app = null, cam = null, shown = null, sorts = 0, lastKey = null;
const defaults = {};  // app.scene.gsplat settings as the engine made them, for the keys options have touched

function load(url) {
  const sog = url.endsWith(".sog");  // a gsplat asset, drawn by a gsplat component; glTF: a container
  return new Promise((resolve, reject) => {
    const asset = new pc.Asset(url, sog ? "gsplat" : "container", { url });
    asset.once("error", e => reject(new Error("loading " + url + ": " + e)));
    asset.ready(a => {
      if (!sog) { resolve(a.resource.instantiateRenderEntity()); return; }
      const e = new pc.Entity(url);
      e.addComponent("gsplat", { asset: a });
      resolve(e);
    });
    app.assets.add(asset);
    app.assets.load(asset);
  });
}

// Render the file at `url` from camera-to-world c2w (16 numbers, column-major) with vertical field of view fov
// (degrees) on a w x h canvas, app.scene.gsplat settings `options`: {png: the canvas as a PNG data URL, frames: how
// many renders it took, sorts: sort results received, settled: whether a sort for this camera had come back and
// three readbacks in a row agreed}.
window.pcRender = async ({ url, c2w, fov, w, h, options, minFrames, maxFrames }) => {
  if (app === null) {
    const canvas = document.createElement("canvas");
    canvas.width = w; canvas.height = h;
    document.body.appendChild(canvas);
    app = new pc.Application(canvas, { graphicsDeviceOptions: { deviceTypes: ["webgl2"], antialias: false,
                                                                 preserveDrawingBuffer: true } });
    app.setCanvasFillMode(pc.FILLMODE_NONE);
    app.autoRender = false;
    cam = new pc.Entity("camera");
    cam.addComponent("camera", { fov, horizontalFov: false, nearClip: 0.01, farClip: 1000,
                                 clearColor: new pc.Color(1, 1, 1, 1) });
    app.root.addChild(cam);
    app.scene.on("gsplat:sorted", () => { sorts++; });
    app.start();
  }
  app.setCanvasResolution(pc.RESOLUTION_FIXED, w, h);
  const gs = app.scene.gsplat;
  for (const k of Object.keys(defaults)) if (!(k in options) && gs[k] !== defaults[k]) gs[k] = defaults[k];
  for (const [k, v] of Object.entries(options)) {
    if (!(k in defaults)) defaults[k] = gs[k];
    if (gs[k] !== v) gs[k] = v;
  }
  if (!entities.has(url)) entities.set(url, await load(url));
  const e = entities.get(url);
  if (shown !== e) {
    if (shown !== null) shown.enabled = false;
    if (e.parent === null) app.root.addChild(e); else e.enabled = true;
    shown = e;
  }
  const m = new pc.Mat4();
  m.set(c2w);
  cam.camera.fov = fov;
  cam.setPosition(m.getTranslation());
  cam.setRotation(new pc.Quat().setFromMat4(m));
  // a new pose or file, or a new work-buffer format (the work buffer made again), is sorted again by the worker;
  // the same again is not, even at another size, field of view or shader setting (minPixelSize, antiAlias...)
  const key = JSON.stringify([url, c2w, gs.dataFormat]);
  const needSort = key !== lastKey;
  lastKey = key;
  const s0 = sorts;
  let prev = null, same = 0;
  for (let k = 1; k <= maxFrames; k++) {
    app.renderNextFrame = true;
    await frame();
    await frame();
    const png = app.graphicsDevice.canvas.toDataURL("image/png");
    const ready = !needSort || sorts > s0;
    same = ready && png === prev ? same + 1 : 0;
    if (k >= minFrames && same >= 2) return { png, frames: k, sorts: sorts - s0, settled: true };
    prev = ready ? png : null;
  }
  return { png: prev, frames: maxFrames, sorts: sorts - s0, settled: false };
};
window.pcReady = true;
</script>""").replace("MODULE", MODULE)


class PlayCanvasPage(WebPage):
    """One headless Chromium showing the PlayCanvas page, for several renders (files, poses, settings) in a row;
    a context manager (close() ends the browser and the server)."""

    name = "PlayCanvas"

    def __init__(self, chromium: str, profile: Path, size: tuple[int, int] = (400, 400)):
        """Start the server and the browser (window `size` (w, h)) and load the page; RuntimeError with the page's
        errors when the engine's module does not load within 60 s."""
        super().__init__(chromium, profile, size, PAGE, "window.pcReady === true")

    def render(self, file: Path, c2w: np.ndarray, camera: Camera, flip: np.ndarray | None = None,
               options: dict | None = None, min_frames: int = 3, max_frames: int = 60) -> np.ndarray:
        """PlayCanvas's render [H, W, 3] in [0, 1] of a .glb, .gltf or .sog `file` seen from c2w [4, 4] (OpenGL
        camera-to-world in the capture's coordinates) through the pinhole `camera` (splat_pages.fov_y). The
        engine's camera is flip @ c2w, in the file's own coordinates: flip None is F for glTF (nerfkit writes
        glTF turned by F) and np.eye(4), the pose as given, for a .sog (the capture's axes). options: app.scene.gsplat settings (None or {}: the engine's
        defaults; PRECISE). self.last says how many renders it took. RuntimeError, with the page's errors,
        when PlayCanvas fails or its renders do not settle within max_frames."""
        file = Path(file)
        suffix = file.suffix.lower()
        if suffix not in (".glb", ".gltf", ".sog"):
            raise ValueError(f"the page draws .glb, .gltf and .sog files, not {file.name}")
        default = np.eye(4) if suffix == ".sog" else F  # a .sog is in the capture's axes (formats/sog.py)
        pose = np.asarray(default if flip is None else flip, np.float64) @ np.asarray(c2w, np.float64)
        w, h = int(camera.width), int(camera.height)
        args = {"url": self._url(file), "c2w": pose.T.reshape(-1).tolist(), "fov": fov_y(camera), "w": w, "h": h,
                "options": options or {}, "minFrames": int(min_frames), "maxFrames": int(max_frames)}
        return self._draw("pcRender", file, args, timeout=180)


def playcanvas_vs_nerfkit(page: PlayCanvasPage, file: Path, c2w: np.ndarray, camera: Camera,
                          png: Path | None = None, flip: np.ndarray | None = None,
                          options: dict | None = None, model: bool = False) -> dict:
    """{"psnr": dB, "playcanvas": image, "nerfkit": image, "frames": PlayCanvas's renders, "sorts": sort results
    it waited for} of PlayCanvas's render of a .glb/.gltf (page.render with flip, options) against nerfkit's
    render of the same file as nerfkit reads it back (formats.read_gaussians: capture coordinates, the file's SH
    degree), clipped to [0, 1], from the same camera (c2w in the capture's coordinates). model: also
    "model": playcanvas_model of the same Gaussians and "psnr_model", PlayCanvas's render against it. png: where
    to write the images side by side (nerfkit, PlayCanvas and, with model, the model)."""
    from nerfkit.core.metrics import psnr
    from nerfkit.models.splat.formats import read_gaussians
    from nerfkit.models.splat.gaussians import render

    g, degree, _ = read_gaussians(file)
    want = np.clip(render(g, c2w, camera, sh_degree=degree, depth=False)["rgb"], 0.0, 1.0)
    got = page.render(file, c2w, camera, flip, options)
    out = {"psnr": float(psnr(got, want)), "playcanvas": got, "nerfkit": want, "frames": page.last.get("frames"),
           "sorts": page.last.get("sorts")}
    if model:
        out["model"] = playcanvas_model(g, c2w, camera, degree)
        out["psnr_model"] = float(psnr(got, out["model"]))
    if png is not None:
        import imageio.v3 as iio

        row = [want, got] + ([out["model"]] if model else [])
        iio.imwrite(png, np.round(np.concatenate(row, 1) * 255).astype(np.uint8))
    return out


def playcanvas_model(g: dict, c2w: np.ndarray, camera: Camera, sh_degree: int = 3,
                     background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """[H, W, 3] in [0, 1]: what PlayCanvas should draw of Gaussians g (capture coordinates) from c2w, by its rules
    as read from its source, on nerfkit's projection and SH colours (gaussians.splat_inputs with dilation
    DILATION, 0.075 px^2): per pixel centre, alpha = o (e^{-s} - e^{-4}) / (1 - e^{-4}) for 0 <= s <= KERNEL_END
    (s = d^2 / 2), dropped under ALPHA_CLIP, blended over `background` in z-depth order with no 0.99 clamp and no
    T_MIN stop (numpy, in blocks of pixels). It leaves out the engine's quantisation and 8-bit blending, and
    nerfkit's own Jacobian clamp is kept (FOV_CLAMP, Gaussians far outside the view)."""
    import jax
    import jax.numpy as jnp

    from nerfkit.models.splat.gaussians import all_sh, band_mask, intrinsics_of, splat_inputs, to_device

    p = to_device(g)
    w, h = int(camera.width), int(camera.height)
    inputs = jax.jit(splat_inputs, static_argnames=("width", "height", "dilation"))
    proj, colours, opacity = inputs(p, jnp.asarray(c2w, jnp.float32), jnp.asarray(intrinsics_of(camera), jnp.float32),
                                    width=w, height=h, sh=all_sh(p) * band_mask(sh_degree), dilation=DILATION)
    live = np.asarray(proj["radii"]) > 0
    order = np.argsort(np.asarray(proj["depths"])[live], kind="stable")  # front to back
    m = np.asarray(proj["means2d"], np.float64)[live][order]
    q = np.asarray(proj["conics"], np.float64)[live][order]
    col = np.asarray(colours, np.float64)[live][order]
    op = np.asarray(opacity, np.float64)[live][order]
    cov = np.asarray(proj["cov2d"], np.float64)[live][order]
    reach = np.sqrt(2.0 * KERNEL_END * np.maximum(cov[:, 0, 0], cov[:, 1, 1]))  # the kernel's end, in y
    out = np.empty((h, w, 3))
    e4 = np.exp(-KERNEL_END)
    u = np.arange(w) + 0.5
    rows = max(1, (1 << 20) // max(w * len(m), 1))
    for top in range(0, h, rows):
        v = np.arange(top, min(h, top + rows)) + 0.5
        near = np.abs(m[:, 1] - 0.5 * (v[0] + v[-1])) <= reach + 0.5 * (v[-1] - v[0])  # those that reach the rows
        pix = np.stack(np.broadcast_arrays(u[None, :], v[:, None]), -1).reshape(-1, 2)
        mb, qb, cb, ob = m[near], q[near], col[near], op[near]
        d = mb[None] - pix[:, None]
        s = 0.5 * (qb[:, 0] * d[..., 0] ** 2 + qb[:, 2] * d[..., 1] ** 2) + qb[:, 1] * d[..., 0] * d[..., 1]
        alpha = ob * (np.exp(-np.clip(s, 0.0, KERNEL_END)) - e4) / (1.0 - e4)
        alpha = np.where((s >= 0.0) & (s <= KERNEL_END) & (alpha >= ALPHA_CLIP), alpha, 0.0)
        trans = np.cumprod(np.concatenate([np.ones((len(pix), 1)), 1.0 - alpha], 1), 1)
        block = (trans[:, :-1] * alpha) @ cb + trans[:, -1:] * np.asarray(background, np.float64)
        out[top:top + len(v)] = block.reshape(len(v), w, 3)
    return np.clip(out, 0.0, 1.0).astype(np.float32)
