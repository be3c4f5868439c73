"""A third-party renderer draws the exported .ply: viser's Gaussian splats (its own WebGL sorter and shader) in
headless Chromium, fed from the file as plyfile reads it, against nerfkit's rasteriser.

viser takes one colour per Gaussian, so both render the degree-0 colour SH_C0 f_dc + 0.5; its camera is set
to a training pose and its render (client.camera.get_render, at the browser canvas's own size and vertical
field of view) is compared with nerfkit's render of the same pinhole camera. A screenshot of the two side by
side is kept (NERFKIT_VISER_SCREENSHOT=/path.png copies it out).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import time

import numpy as np
from chromium import Chromium

from nerfkit.cli.main import main
from nerfkit.core.metrics import psnr
from nerfkit.models.splat.model import render
from nerfkit.models.splat.ply import import_ply
from nerfkit.models.splat.project import SH_C0, covariance_3d
from nerfkit.models.splat.transform import rotation_to_quat
from nerfkit.rays.cameras import Camera


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_viser_draws_the_exported_file_like_nerfkit(chromium, splat_run, tmp_path):
    import imageio.v3 as iio
    import jax.numpy as jnp
    import viser

    scene, run = splat_run
    ply = tmp_path / "scene.ply"
    assert main(["export", "splat", str(run), "--out", str(ply)]) == 0
    g = import_ply(ply)  # the file as written, in the capture's coordinates
    sc = json.loads((run / "scene.json").read_text())
    cov = np.asarray(covariance_3d(jnp.asarray(g["log_scales"]), jnp.asarray(g["quats"])))
    rgb = np.clip(SH_C0 * g["sh_dc"][:, 0] + 0.5, 0.0, 1.0)
    opacity = 1.0 / (1.0 + np.exp(-g["opacity"]))
    port = free_port()
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    browser = Chromium(chromium, tmp_path / "profile", 400, 400, webgl=True)
    try:
        server.scene.add_gaussian_splats("/splats", centers=g["means"], covariances=cov, rgbs=rgb,
                                         opacities=opacity[:, None])
        browser.open_page()
        browser.navigate(f"http://127.0.0.1:{port}")
        t0 = time.time()
        while not server.get_clients() and time.time() - t0 < 60:
            time.sleep(0.2)
        client = next(iter(server.get_clients().values()))
        pose = np.asarray(sc["train_poses"][0], np.float64)  # Blender scene: capture frame = run frame
        client.camera.wxyz = rotation_to_quat(pose[:3, :3] @ np.diag([1.0, -1.0, -1.0]))  # OpenCV camera axes
        client.camera.position = pose[:3, 3]
        client.camera.fov = float(2 * np.arctan(0.5 * sc["height"] / Camera.from_json(sc["camera"]).fy))
        time.sleep(1.0)
        w, h, fov = client.camera.image_width, client.camera.image_height, client.camera.fov
        got = client.camera.get_render(height=h, width=w)[..., :3].astype(np.float32) / 255.0
    finally:
        browser.close()
        server.stop()
    cam = Camera.pinhole(w, h, 0.5 * h / np.tan(0.5 * fov))
    want = np.clip(render(g, pose, cam, sh_degree=0)["rgb"], 0.0, 1.0)
    assert want.std() > 0.05, "a blank reference image: a bad test camera"
    score = float(psnr(got, want))
    shot = tmp_path / "viser_vs_nerfkit.png"
    iio.imwrite(shot, (np.concatenate([want, got], 1) * 255).astype(np.uint8))
    if os.environ.get("NERFKIT_VISER_SCREENSHOT"):
        shutil.copy(shot, os.environ["NERFKIT_VISER_SCREENSHOT"])
    print(f"viser vs nerfkit: {score:.2f} dB at {w}x{h}")
    assert score >= 35.0, score  # measured 43.3 dB (the shared 200-step run, 500 x 313; 24.5 dB after 40 steps,
    # when half-transparent Gaussians tens of pixels wide fill the view and the two renderers cut them differently)
