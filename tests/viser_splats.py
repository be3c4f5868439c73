"""viser's Gaussian splats (a third-party WebGL renderer) drawing Gaussians in headless Chromium, as a user's
browser would: shared by tests/models/splat/test_third_party.py and benchmarks/splat_third_party.py.

viser takes one colour per Gaussian, so it is given the degree-0 colour SH_C0 f_dc + 0.5. Its camera is set
to a pinhole pose (OpenGL camera-to-world, in the Gaussians' frame) and its render (client.camera.get_render,
at the browser canvas's own size and vertical field of view) is returned with that camera, so nerfkit can
render the same one.
"""

from __future__ import annotations

import socket
import time
from pathlib import Path

import numpy as np
from chromium import Chromium

from nerfkit.rays.cameras import Camera
from nerfkit.viewer.frames import viser_from_c2w
from nerfkit.viewer.splats import browser_splats


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def viser_render(chromium: str, profile: Path, gaussians: dict, c2w: np.ndarray, fov_y: float,
                 size: int = 400) -> tuple[np.ndarray, Camera]:
    """(viser's render [h, w, 3] in [0, 1], the pinhole Camera it drew) of `gaussians` (import_ply's dict:
    means, log_scales, quats, sh_dc, opacity logits) seen from c2w [4, 4] with vertical field of view fov_y;
    viser is handed what nerfkit's viewer hands it (viewer/splats.browser_splats)."""
    import viser

    splats = browser_splats(gaussians, {"active": np.ones(len(gaussians["means"]), bool)})
    port = free_port()
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    browser = Chromium(chromium, profile, size, size, webgl=True)
    try:
        server.scene.add_gaussian_splats("/splats", **splats)
        browser.open_page()
        browser.navigate(f"http://127.0.0.1:{port}")
        t0 = time.time()
        while not server.get_clients() and time.time() - t0 < 60:
            time.sleep(0.2)
        if not server.get_clients():
            raise RuntimeError(f"no browser connected to viser on port {port} within 60 s")
        client = next(iter(server.get_clients().values()))
        got = settled_render(client, c2w, float(fov_y), deadline=time.time() + 90)
        w, h, fov = client.camera.image_width, client.camera.image_height, client.camera.fov
    finally:
        browser.close()
        server.stop()
    return got, Camera.pinhole(w, h, 0.5 * h / np.tan(0.5 * fov))


def settled_render(client, c2w: np.ndarray, fov_y: float, deadline: float) -> np.ndarray:
    """The browser's render [h, w, 3] in [0, 1] once it draws the pose c2w with vertical field of view fov_y.

    A fixed wait is a race on a loaded machine (CI once rendered viser's start-up view: 13 dB): the browser's
    first camera report can arrive after the pose was sent and overwrite it, and its sorter can lag the camera.
    So: wait for the browser's own camera report, send the pose, wait until the browser reports that pose back
    (sending it again when it reports another), then render until two renders in a row agree, and start over if its
    last report is then another pose.
    """
    reports = []
    client.camera.on_update(lambda cam: reports.append((cam.wxyz.copy(), cam.position.copy(), cam.fov)))
    want_wxyz, want_pos = viser_from_c2w(c2w)
    want_wxyz, want_pos = np.asarray(want_wxyz, float), np.asarray(want_pos, float)

    def wait(ok, what):
        while not ok():
            if time.time() > deadline:
                raise RuntimeError(f"viser: {what}, within the time allowed")
            time.sleep(0.1)

    wait(lambda: client.camera._state.update_timestamp != 0.0, "the browser never reported its camera")

    def there(r):  # q and -q are one rotation
        wxyz, pos, fov = r
        return (min(np.abs(wxyz - want_wxyz).max(), np.abs(wxyz + want_wxyz).max()) < 1e-4
                and np.abs(pos - want_pos).max() < 1e-4 and abs(fov - fov_y) < 1e-5)

    while True:
        while not (reports and there(reports[-1])):
            seen = len(reports)
            client.camera.wxyz, client.camera.position = want_wxyz, want_pos
            client.camera.fov = fov_y
            wait(lambda: len(reports) > seen, "the browser never reported the pose sent")
            if reports and not there(reports[-1]):
                time.sleep(0.2)  # let the reply settle before sending again
        prev = None
        while True:
            h, w = client.camera.image_height, client.camera.image_width
            got = client.camera.get_render(height=h, width=w)[..., :3].astype(np.float32) / 255.0
            if prev is not None and prev.shape == got.shape and np.abs(got - prev).max() <= 2 / 255:
                break
            if time.time() > deadline:
                raise RuntimeError("viser: two renders in a row never agreed, within the time allowed")
            prev = got
            time.sleep(0.5)
        # Should the browser have reported another camera since (a camera message still on its way), those
        # renders may be of another view: start over.
        if there(reports[-1]):
            return got
