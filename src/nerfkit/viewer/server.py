"""nerfkit's interactive viewer: a viser server that renders the field for each connected browser.

viser (the viewer library nerfstudio uses) owns the web page, the 3D scene (training cameras
as frustums with their photos, the scene box, camera-path keyframes), the GUI and the
browser's camera. nerfkit only renders: for every client whose camera or view settings
changed, one frame, sent as the page's background image. A splat run's Gaussians can instead be
drawn by the browser itself (viser's splats, splats.py: "Drawn by", the default for splats): then
nothing is rendered here but saved views, and new parameters are handed over at most every few
seconds while training.

Progressive rendering. While a camera moves (its last update is younger than STILL_AFTER s),
frames are previews that adapt to keep TARGET_FPS (preview_quality): first the march coarsens
(render/wavefront.coarser: stride s marches s steps as one, ~s times fewer samples; on lego s = 3 renders
256x256 in 0.15 s instead of 0.35 s, 30 dB against the full frame), then the resolution drops
(preview_size: the side scaled by sqrt(target / seconds), clamped to [1/2, 2] per frame and to
[16 px, the chosen resolution], as nerfstudio's viewer does; the browser stretches the image);
a fast machine previews at full quality. Once the camera rests, the frame is rendered again at
full resolution with the full march. Frames are
rendered by whoever calls `render_pending()`: the viewer's own loop (`nerfkit view`), or the
training loop between steps (`nerfkit train --viewer`), where a duty-cycle gate keeps the
viewer's share of the wall time at most `max_fraction`: after a frame that took s seconds,
the next is not started before s (1 - f) / f seconds have passed (the first frame, which
compiles the renderer, is not gated).

Cameras: frames.py (viser's OpenCV frames, nerfkit's OpenGL c2w).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nerfkit.core.viz import save_png, to_uint8
from nerfkit.rays.camera_path import write_camera_path
from nerfkit.rays.cameras import look_at
from nerfkit.render.wavefront import WavefrontRenderer, coarser
from nerfkit.viewer.frames import (
    DRAWN_BY,
    MODES,
    c2w_from_viser,
    preview_quality,
    shade_output,
    view_camera,
    viser_from_c2w,
)
from nerfkit.viewer.splats import SplatLayer


def _unused_path(folder: Path, pattern: str) -> Path:
    """folder / pattern.format(k) for the smallest k not yet taken (earlier saves are never overwritten)."""
    k = 0
    while (folder / pattern.format(k)).exists():
        k += 1
    return folder / pattern.format(k)


@dataclass
class SceneView:
    """What the viewer draws besides the field (normalised scene coordinates)."""

    poses: np.ndarray  # [N, 4, 4] training camera-to-world (OpenGL)
    cameras: list  # [N] Camera
    thumbnails: list | None = None  # [N] uint8 [h, w, 3], or None
    bound: float = 1.5  # box half-size (bounded) or the contraction radius (unbounded)
    unbounded: bool = False
    background: tuple = (1.0, 1.0, 1.0)


@dataclass
class _Client:
    handle: object
    version: int = 0  # bumped on every camera update
    moved_at: float = 0.0
    shown: tuple | None = None  # (version, params version, mode, resolution, full) of the frame on screen
    last_image: np.ndarray | None = None
    frames: list = field(default_factory=list)  # (wall time, seconds, full) of recent frames
    aspect: float = 1.0  # the browser canvas's last non-degenerate width / height

    def note_camera(self) -> None:
        """Record a camera update; a canvas reported as 0 px high (the page resizing) keeps the last aspect."""
        self.version += 1
        self.moved_at = time.perf_counter()
        w, h = self.handle.camera.image_width, self.handle.camera.image_height
        if w > 0 and h > 0:
            self.aspect = w / h


class Viewer:
    """A viser server showing `model` with parameters that may change (training) or not."""

    TARGET_FPS = 6.0  # frames per second while the camera moves (previews adapt their march and resolution)
    MAX_STRIDE = 3  # the coarsest preview march (lego 256x256: 0.35 / 0.21 / 0.15 / 0.14 s at strides 1-4)
    STILL_AFTER = 0.2

    def __init__(self, renderer, scene: SceneView, out_dir: Path, host: str = "127.0.0.1", port: int = 7007,
                 max_fraction: float = 1.0, verbose: bool = True, show_cameras: bool = True, splats: bool = False):
        """splats: the model is Gaussian splats, which the browser can draw itself (splats.py): a "Drawn by"
        choice, the browser by default."""
        import viser

        self.renderer, self.scene, self.out_dir = renderer, scene, Path(out_dir)
        self.max_fraction = max_fraction
        self._lock = threading.Lock()
        self._clients: dict[int, _Client] = {}
        self._params = None
        self._params_version = 0
        self.step = 0
        self._gate = 0.0
        self._saves: list = []  # (client id, kind) requests, served by render_pending
        self.spent: list[float] = []  # seconds of each rendered frame (frame time incl. encoding and sending)
        self.frames_rendered = 0
        self.preview_side = 64  # adapted by preview_quality() after every preview, with the march stride
        self.preview_stride = 1
        self._renderers = {1: renderer}  # by march stride (render/wavefront.coarser), compiled on first use
        self._compiled: set[int] = set()  # strides whose renderer has compiled (a frame or warm_up)
        self.keyframes: list[tuple[np.ndarray, float]] = []
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.host, self.port = host, self.server.get_port()
        self.server.scene.set_up_direction("+z")
        self.show_cameras = show_cameras
        self._draw_scene()
        self.splats = SplatLayer(self.server.scene) if splats else None
        self._build_gui()
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(lambda c: self._clients.pop(c.client_id, None))

    # -- state ------------------------------------------------------------------------
    def set_params(self, params, aux, step: int) -> None:
        """New field parameters (JAX arrays are immutable: a reference is enough)."""
        with self._lock:
            self._params = (params, aux)
            self._params_version += 1
            self.step = step

    def _on_connect(self, client) -> None:
        st = _Client(client)
        self._clients[client.client_id] = st
        if len(self.scene.poses):  # start beside the first training camera (15 deg around the up axis)
            a = math.radians(15.0)
            rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
            wxyz, pos = viser_from_c2w(look_at(rot @ self.scene.poses[0][:3, 3], np.zeros(3)))
            with client.atomic():
                client.camera.wxyz, client.camera.position = wxyz, pos
                client.camera.look_at = np.zeros(3)

        @client.camera.on_update
        def _(_cam) -> None:
            st.note_camera()

    # -- scene and GUI ----------------------------------------------------------------
    def _draw_scene(self) -> None:
        s, sc = self.scene, self.server.scene
        self._frustums = []
        centres = s.poses[:, :3, 3] if len(s.poses) else np.zeros((1, 3))
        size = 0.06 * float(np.median(np.linalg.norm(centres, axis=1)) or 1.0)
        for k, (c2w, cam) in enumerate(zip(s.poses, s.cameras)):
            wxyz, pos = viser_from_c2w(c2w)
            thumb = s.thumbnails[k] if s.thumbnails is not None else None
            fov = 2 * math.atan(0.5 * cam.height / cam.fy)
            self._frustums.append(sc.add_camera_frustum(f"/train_cameras/{k:04d}", fov=fov,
                                  aspect=cam.width / cam.height, scale=size, image=thumb, format="jpeg",
                                  wxyz=wxyz, position=pos, color=(60, 90, 200), visible=self.show_cameras))
        b = s.bound
        corners = np.array([[x, y, z] for x in (-b, b) for y in (-b, b) for z in (-b, b)])
        edges = [(i, j) for i in range(8) for j in range(i + 1, 8) if (i ^ j).bit_count() == 1]
        sc.add_line_segments("/scene_box", corners[np.array(edges)], (230, 120, 30),
                             thickness=2.0, thickness_units="screen")

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.info = gui.add_markdown("waiting for the first frame...")
        self.drawn_by = None
        if self.splats is not None:
            self.drawn_by = gui.add_dropdown("Drawn by", DRAWN_BY, initial_value=DRAWN_BY[0],
                                             hint="the browser draws the Gaussians itself (viser's splats, degree-0 "
                                                  "colour) at its own frame rate; nerfkit renders every frame with "
                                                  "its rasteriser (view-dependent colour, depth, opacity)")
            self.drawn_by.on_update(lambda _e: self._switch_drawing())
        self.mode = gui.add_dropdown("Output", MODES, initial_value="RGB")
        self.mode.on_update(lambda _e: self._mode_changed())
        self.resolution = gui.add_number("Max resolution", 256, min=32, max=2048, step=16,
                                         hint="longest side of the live view (moving: previews keep 6 frames/s)")
        self.out_res = gui.add_number("Save resolution", 800, min=32, max=4096, step=16,
                                      hint="longest side of saved views and of camera-path renders")
        show = gui.add_checkbox("Training cameras", self.show_cameras,
                                hint="drawing them with their photos costs a browser without a GPU ~0.2 cores")

        @show.on_update
        def _(_e) -> None:
            for h in self._frustums:
                h.visible = show.value

        gui.add_button("Save this view", hint="render at the save resolution into RUN/views/").on_click(
            lambda e: self._request(e.client, "view"))
        with gui.add_folder("Camera path"):
            self.path_seconds = gui.add_number("Seconds", 4.0, min=0.5, max=600.0, step=0.5)
            self.path_fps = gui.add_number("FPS", 24, min=1, max=120, step=1)
            self.path_loop = gui.add_checkbox("Loop", False)
            gui.add_button("Add keyframe").on_click(lambda e: self._add_keyframe(e.client))
            gui.add_button("Clear keyframes").on_click(lambda _e: self._clear_keyframes())
            gui.add_button("Save camera path", hint="RUN/camera_paths/*.json; render it with "
                                                    "nerfkit render RUN --camera-path FILE").on_click(
                lambda e: self._request(e.client, "path"))

    @property
    def browser_draws(self) -> bool:
        """The browser draws the Gaussians (no frames are rendered here, but saved views are)."""
        return self.drawn_by is not None and self.drawn_by.value == DRAWN_BY[0]

    def _mode_changed(self) -> None:
        """Depth or opacity are nerfkit's renders: picking one while the browser draws hands drawing to nerfkit."""
        if self.browser_draws and self.mode.value != "RGB":
            self.drawn_by.value = DRAWN_BY[1]  # its on_update switches the drawing

    def _switch_drawing(self) -> None:
        self.splats.set_visible(self.browser_draws)
        for st in list(self._clients.values()):
            st.shown = None  # nerfkit renders afresh; the browser gets its background back clear
            if self.browser_draws:
                st.handle.scene.set_background_image(None)

    def _show_splats(self, now: float) -> float:
        """Hand new parameters to the browser's splats when the throttle lets them through."""
        if self._clients and self.splats.due(self._params_version, now):
            self.splats.show(*self._params, self._params_version, now, visible=True)
            self.frames_rendered += 1
            self.info.content = (f"**step {self.step}** · {self.splats.count:,} Gaussians drawn by the browser "
                                 f"(viser's splats, degree-0 colour)")
            return self._spend(now)
        return 0.0

    def _request(self, client, kind: str) -> None:
        with self._lock:
            self._saves.append((client.client_id, kind))

    def _add_keyframe(self, client) -> None:
        cam = client.camera
        c2w = c2w_from_viser(cam.wxyz, cam.position)
        self.keyframes.append((c2w, math.degrees(cam.fov)))
        k = len(self.keyframes) - 1
        st = self._clients.get(client.client_id)
        aspect = st.aspect if st is not None else 1.0
        self.server.scene.add_camera_frustum(f"/keyframes/{k:03d}", fov=cam.fov, aspect=aspect, scale=0.1,
                                             wxyz=cam.wxyz, position=cam.position, color=(220, 40, 40))
        client.add_notification(f"keyframe {k + 1}", "added", auto_close_seconds=2.0)

    def _clear_keyframes(self) -> None:
        for k in range(len(self.keyframes)):
            self.server.scene.remove_by_name(f"/keyframes/{k:03d}")
        self.keyframes.clear()

    # -- rendering --------------------------------------------------------------------
    @property
    def max_stride(self) -> int:
        """The coarsest preview march: MAX_STRIDE for wavefront renderers (the fields that march), 1 for the
        others, and 1 while training, where the duty-cycle gate, not the render time, sets the frame rate
        and each stride's compile (~5 s on 2 cores) would be training time."""
        return self.MAX_STRIDE if isinstance(self.renderer, WavefrontRenderer) and self.max_fraction >= 1.0 else 1

    def _renderer(self, stride: int):
        if stride not in self._renderers:
            self._renderers[stride] = coarser(self.renderer, stride)
        return self._renderers[stride]

    def _warm_up_next(self, now: float) -> float:
        """Idle time: compile the next march stride not compiled yet (all of its shading budgets, ~5 s each on
        2 cores, or a load from the compile cache), so that previews do not stall on compiles when the
        camera starts moving. Returns the seconds spent."""
        cold = [s for s in range(1, self.max_stride + 1) if s not in self._compiled]
        if not cold or not self._clients:
            return 0.0
        self._renderer(cold[0]).warm_up(*self._params)
        self._compiled.add(cold[0])
        return self._spend(now)

    def _spend(self, now: float) -> float:
        """Book the seconds since `now` as the viewer's and close the duty-cycle gate for long enough."""
        spent = time.perf_counter() - now
        self.spent.append(spent)
        if self.max_fraction < 1.0 and len(self.spent) > 1:  # (the first frame compiles the renderer)
            self._gate = time.perf_counter() + spent * (1.0 - self.max_fraction) / self.max_fraction
        return spent

    def _render(self, st: _Client, max_side: int, mode: str, stride: int = 1) -> tuple[np.ndarray, float]:
        cam = st.handle.camera
        c2w = c2w_from_viser(cam.wxyz, cam.position)
        params, aux = self._params
        t0 = time.perf_counter()
        out = self._renderer(stride).render_camera(params, aux, c2w.astype(np.float32),
                                                    view_camera(cam.fov, st.aspect, max_side))
        img = to_uint8(shade_output(out, mode, self.scene.background))
        return img, time.perf_counter() - t0

    def _serve_save(self, cid: int, kind: str) -> None:
        st = self._clients.get(cid)
        if st is None:
            return
        client, cam = st.handle, st.handle.camera
        side = int(self.out_res.value)
        if kind == "view":
            img, _ = self._render(st, side, self.mode.value)
            path = _unused_path(self.out_dir / "views", "view_{:04d}.png")
            save_png(path, img)
        else:
            if not self.keyframes:
                client.add_notification("no keyframes", "add keyframes first", color="red", auto_close_seconds=4.0)
                return
            c = view_camera(cam.fov, st.aspect, side)
            path = write_camera_path(_unused_path(self.out_dir / "camera_paths", "camera_path_{:03d}.json"),
                                     [k[0] for k in self.keyframes], [k[1] for k in self.keyframes], c.width,
                                     c.height, float(self.path_seconds.value), int(self.path_fps.value),
                                     bool(self.path_loop.value))
        client.add_notification("saved", str(path), auto_close_seconds=6.0)
        print(f"viewer: wrote {path}", flush=True)

    def render_pending(self) -> float:
        """Serve one save request or render one frame for the client that needs it most; returns the
        seconds spent (0 when there was nothing to do or the duty-cycle gate is closed)."""
        now = time.perf_counter()
        if self._params is None:
            return 0.0
        with self._lock:
            save = self._saves.pop(0) if self._saves else None
        if save is not None:
            try:
                self._serve_save(*save)
            except OSError as e:  # e.g. a full disk: say so, keep serving (and training)
                print(f"viewer: could not save: {e}", flush=True)
            return time.perf_counter() - now
        if now < self._gate:
            return 0.0
        if self.browser_draws:
            return self._show_splats(now)
        side, mode = int(self.resolution.value), self.mode.value
        todo = []
        for st in list(self._clients.values()):
            if st.version == 0:  # no camera from this browser yet
                continue
            full = now - st.moved_at >= self.STILL_AFTER
            key = (st.version, self._params_version, mode, side, full)
            if st.shown is not None and (st.shown == key or (st.shown[0] == st.version and st.shown[4] and not full)):
                continue
            todo.append((st.moved_at, st, key))
        if not todo:
            return self._warm_up_next(now) if self.max_stride > 1 else 0.0
        _, st, key = min(todo, key=lambda x: x[0])  # the longest-waiting client first
        stride = 1 if key[4] else self.preview_stride
        first_use = stride not in self._compiled  # (its first frame compiles: no measure of speed)
        self._compiled.add(stride)
        try:
            img, secs = self._render(st, side if key[4] else min(side, self.preview_side), mode, stride)
        except Exception as e:  # noqa: BLE001 - a browser's odd camera must not end a training run
            st.shown = key  # (not retried until the camera moves again)
            print(f"viewer: skipped a frame for browser {st.handle.client_id}: {type(e).__name__}: {e}", flush=True)
            return time.perf_counter() - now
        if not key[4] and not first_use:
            self.preview_stride, self.preview_side = preview_quality(
                stride, min(side, self.preview_side), secs, 1.0 / self.TARGET_FPS, side, self.max_stride)
        st.handle.scene.set_background_image(img, format="jpeg", jpeg_quality=90)
        st.shown, st.last_image = key, img
        st.frames = (st.frames + [(time.perf_counter(), secs, key[4])])[-30:]
        self.frames_rendered += 1
        spent = self._spend(now)
        self._update_info(st, img, secs, key[4], stride)
        return spent

    def _update_info(self, st: _Client, img: np.ndarray, secs: float, full: bool, stride: int) -> None:
        moving = [f for f in st.frames if not f[2]]
        rate = f" · {1.0 / np.mean([f[1] for f in moving]):.1f} frames/s moving" if moving else ""
        kind = "still" if full else ("preview" if stride == 1 else f"preview (march x{stride})")
        self.info.content = f"**step {self.step}** · {img.shape[1]}x{img.shape[0]} {kind} in {secs:.2f} s{rate}"

    def serve_forever(self, idle_sleep: float = 0.01) -> None:
        """Render frames until Ctrl-C (KeyboardInterrupt reaches the caller, which closes the viewer)."""
        while True:
            if not self.render_pending():
                time.sleep(idle_sleep)

    def close(self) -> None:
        self.server.stop()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"
