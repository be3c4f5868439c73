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
        client.camera.wxyz, client.camera.position = viser_from_c2w(c2w)
        client.camera.fov = float(fov_y)
        time.sleep(1.0)
        w, h, fov = client.camera.image_width, client.camera.image_height, client.camera.fov
        got = client.camera.get_render(height=h, width=w)[..., :3].astype(np.float32) / 255.0
    finally:
        browser.close()
        server.stop()
    return got, Camera.pinhole(w, h, 0.5 * h / np.tan(0.5 * fov))
