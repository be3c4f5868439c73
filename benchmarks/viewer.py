"""The viewer's frame rate (moving and still) and its cost to training, in headless Chromium.

    python benchmarks/viewer.py RUN_DIR [--data DATA --steps 300] [--window 480x583] [--seconds 6]

1. `nerfkit view RUN_DIR`'s renderer behind a viser server, a headless Chromium page (--window) connected
   to it. After the first frame, the viewer compiles its coarser preview marches in idle time (timed).
   Then the browser's camera is dragged along an orbit (a new pose every 1/30 s for --seconds; previews
   adapt march stride and resolution to the viewer's TARGET_FPS); frames/s rendered during the drag,
   and the previews' final stride, side and times. Then the camera rests: the full-resolution frame.
2. With --data: the same preset trained for --steps steps with and without the viewer open (a browser
   connected, camera at rest, the live parameters re-rendered under the duty-cycle gate); steps/s of both.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from chromium import Chromium, find_chromium

from nerfkit.rays.cameras import orbit_poses
from nerfkit.render.images import make_renderer
from nerfkit.run.folder import RunFolder
from nerfkit.training.trainer import Trainer
from nerfkit.viewer.frames import viser_from_c2w
from nerfkit.viewer.run import attach_viewer, scene_view_of_run
from nerfkit.viewer.server import Viewer


def wait(cond, timeout=300.0):
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError
        time.sleep(0.002)


def frame_rate(run: Path, binary: str, resolution: int, seconds: float, window=(640, 480)) -> dict:
    run_ = RunFolder(run).load()
    cfg, model, params, aux, step = run_.cfg, run_.model, run_.params, run_.aux, run_.step
    viewer = Viewer(make_renderer(model, cfg.train.chunk), scene_view_of_run(run, cfg), run, port=0)
    viewer.set_params(params, aux, step)
    viewer.resolution.value = resolution
    stop = threading.Event()

    def loop():
        while not stop.is_set():
            if not viewer.render_pending():
                time.sleep(0.002)

    th = threading.Thread(target=loop, daemon=True)
    th.start()
    # A small window: the headless page (software GL on the same cores) echoes more of the drag.
    browser = Chromium(binary, Path(tempfile.mkdtemp()) / "profile", *window)
    try:
        browser.open_page()
        browser.navigate(viewer.url)
        wait(lambda: any(c.version for c in viewer._clients.values()))
        st = next(c for c in viewer._clients.values() if c.version)
        wait(lambda: st.shown is not None and st.shown[4])  # first still frame (compiles)
        t_warm = time.perf_counter()  # the viewer compiles its coarser preview marches in idle time
        wait(lambda: len(viewer._compiled) >= viewer.max_stride)
        warm_up = time.perf_counter() - t_warm
        shapes = []
        # A drag: a new pose every 1/30 s for `seconds`, as the browser reports a moving camera.
        orbit = orbit_poses(viewer.scene.poses, int(30 * seconds))
        n0, v0, t0 = viewer.frames_rendered, st.version, time.perf_counter()
        for c2w in orbit:
            wxyz, pos = viser_from_c2w(c2w)
            with st.handle.atomic():
                st.handle.camera.wxyz, st.handle.camera.position = wxyz, pos
            time.sleep(max(0.0, t0 + (len(shapes) + 1) / 30 - time.perf_counter()))
            shapes.append(st.last_image.shape[:2])
        moving = (viewer.frames_rendered - n0) / (time.perf_counter() - t0)
        previews = [f[1] for f in st.frames if not f[2]]
        updates = st.version - v0
        v = st.version
        t1 = time.perf_counter()
        wait(lambda: st.shown[4] and st.shown[0] == st.version)
        still = time.perf_counter() - t1
        still_render = [f[1] for f in st.frames if f[2]][-1]
    finally:
        stop.set()
        th.join(30)
        browser.close()
        viewer.close()
    return {"moving_fps": moving, "camera_updates": updates, "drag_poses": len(orbit),
            "moving_frame": [int(x) for x in shapes[-1]], "previews": len(previews),
            "preview_seconds_mean": float(sum(previews) / max(1, len(previews))), "preview_side": viewer.preview_side,
            "preview_stride": viewer.preview_stride, "preview_seconds_last": [round(x, 3) for x in previews[-8:]],
            "still_seconds_after_rest": still, "still_render_seconds": still_render,
            "still_frame": [int(x) for x in st.last_image.shape[:2]], "rested_version": v,
            "warm_up_seconds": warm_up}


def training_cost(run: Path, data: Path, binary: str, steps: int) -> dict:
    """steps/s of training without the viewer, with it serving but no browser connected (its own cost:
    the duty-cycled rendering and the server), and with a headless Chromium connected on the same cores."""
    out = {}
    for label in ("without viewer", "viewer, no browser", "with viewer"):
        cfg = RunFolder(run).config()
        cfg.train.max_steps, cfg.train.max_minutes, cfg.train.val_every = steps, None, 10**9
        cfg.train.ckpt_every = 10**9
        tmp = Path(tempfile.mkdtemp())
        trainer = Trainer(data, tmp / "run", cfg, progress=False)
        browser = None
        if label != "without viewer":
            viewer = attach_viewer(trainer, port=0)
        if label == "with viewer":
            browser = Chromium(binary, tmp / "profile", 1024, 768)
            browser.open_page()
            browser.navigate(viewer.url)
            print("  browser connected; waiting for its camera", flush=True)
            wait(lambda v=viewer: any(c.version for c in v._clients.values()), 120)
            print("  training with the viewer open", flush=True)
        try:
            res = trainer.run()
        finally:
            if browser is not None:
                browser.close()
            if trainer.viewer is not None:
                trainer.viewer.close()
        rows = [json.loads(x) for x in (tmp / "run" / "metrics.jsonl").read_text().splitlines()]
        # steps/s after the first 50 steps (compiles excluded), from the logged elapsed times
        a = next(r for r in rows if r["step"] >= 50)
        b = rows[-1]
        out[label] = {"steps_per_second": (b["step"] - a["step"]) / (b["elapsed"] - a["elapsed"]),
                      "overall": res.steps_per_second}
        if label != "without viewer":
            out[label]["frames"] = trainer.viewer.frames_rendered
            out[label]["viewer_seconds"] = sum(trainer.viewer.spent[1:])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--data", type=Path)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--seconds", type=float, default=6.0, help="length of the simulated drag")
    ap.add_argument("--window", default="640x480",
                    help="the browser window, WxH (480x583: a near-square 256x254 canvas)")
    a = ap.parse_args()
    binary = find_chromium()
    if binary is None:
        sys.exit("no Chromium found: apt-get install chromium")
    fr = frame_rate(a.run, binary, a.resolution, a.seconds, tuple(int(x) for x in a.window.split("x")))
    print(f"after the first frame, the viewer compiled its preview marches in {fr['warm_up_seconds']:.1f} s")
    print(f"previews while moving: {fr['previews']} frames, {fr['preview_seconds_mean']:.3f} s each on average "
          f"(render only: {1 / max(fr['preview_seconds_mean'], 1e-9):.1f} frames/s), side adapted to "
          f"{fr['preview_side']} px, march stride {fr['preview_stride']}; the last "
          f"previews took {fr['preview_seconds_last']} s")
    print(f"viewer, {a.resolution} px: {fr['moving_fps']:.1f} frames/s while moving ({fr['moving_frame'][1]}x"
          f"{fr['moving_frame'][0]} previews; the page reported {fr['camera_updates']} of {fr['drag_poses']} poses); "
          f"at rest a {fr['still_frame'][1]}x{fr['still_frame'][0]} frame "
          f"renders in {fr['still_render_seconds']:.2f} s ({fr['still_seconds_after_rest']:.2f} s after the last move)")
    if a.data:
        tc = training_cost(a.run, a.data, binary, a.steps)
        w = tc["without viewer"]["steps_per_second"]
        for label in ("viewer, no browser", "with viewer"):
            v = tc[label]["steps_per_second"]
            print(f"training, {label}: {v:.2f} steps/s vs {w:.2f} without the viewer ({100 * (1 - v / w):.1f}% "
                  f"slower; {tc[label]['frames']} frames, {tc[label]['viewer_seconds']:.1f} s of rendering)")


if __name__ == "__main__":
    main()
