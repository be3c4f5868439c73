"""Opening the viewer on a trained run folder (`nerfkit view`) or on a training run (`--viewer`)."""

from __future__ import annotations

import ipaddress
import socket
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from nerfkit.core.errors import ConfigError, DataError
from nerfkit.core.interrupts import interrupts_raise
from nerfkit.core.viz import background_rgb, to_uint8
from nerfkit.data.loader import read_capture, scene_cameras
from nerfkit.rays.cameras import Camera
from nerfkit.rays.correction import run_poses
from nerfkit.render.images import check_chunk, make_renderer
from nerfkit.run.folder import RunFolder
from nerfkit.training.callbacks import Callback
from nerfkit.viewer.server import SceneView, Viewer

THUMB = 96  # longest side of the photos shown in the training-camera frustums


def is_loopback(host: str) -> bool:
    """Whether `host` (a name or an IPv4 / IPv6 address) only reaches this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_port(port: int, flag: str = "--port") -> None:
    if not 0 <= port <= 65535:
        raise ConfigError(f"{flag} must be in 0..65535 (got {port})")


RESOLVE_SECONDS = 10.0  # a name the resolver has not answered for within this is refused


def resolve(host: str, seconds: float | None = None) -> list:
    """socket.getaddrinfo(host) for a listening TCP socket, in a daemon thread that is given up on after
    `seconds` (default RESOLVE_SECONDS: a resolver that never answers would otherwise hold the command).
    OSError when it fails."""
    seconds = RESOLVE_SECONDS if seconds is None else seconds
    found: list = []

    def ask():
        try:
            found.append(socket.getaddrinfo(host or None, 0, type=socket.SOCK_STREAM,  # '': every interface
                                           flags=socket.AI_PASSIVE))
        except OSError as e:
            found.append(e)

    thread = threading.Thread(target=ask, daemon=True)
    thread.start()
    thread.join(seconds)
    if not found:
        raise TimeoutError(f"no answer from the name resolver in {seconds:g} s")
    if isinstance(found[0], OSError):
        raise found[0]
    return found[0]


def check_host(host: str, flag: str = "--host") -> None:
    """ConfigError unless `host` is a name or address this machine can listen on: it resolves, and a socket
    binds to one of its addresses (port 0, so a busy --port is not the question here)."""
    fix = "use 127.0.0.1 (this machine only) or 0.0.0.0 (every network this machine is on)"
    try:
        infos = resolve(host)
    except OSError as e:
        raise ConfigError(f"{flag} {host}: not a name or address this machine knows ({e.strerror or e}); {fix}")
    last = None
    for family, _, _, _, address in infos:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            try:
                s.bind((address[0], 0))
                return
            except OSError as e:
                last = e
    raise ConfigError(f"{flag} {host}: not an address of this machine ({last.strerror or last}); {fix}")


def check_address(host: str, port: int, flags: tuple[str, str] = ("--host", "--port")) -> None:
    """check_port and check_host (`flags`: how the command spells them), then a warning when the viewer
    would be reachable from other machines."""
    check_port(port, flags[1])
    check_host(host, flags[0])
    if not is_loopback(host):
        print(f"warning: the viewer listens on {host}:{port}, reachable from other machines on this network; "
              f"anyone who can reach it sees the scene (default {flags[0]} 127.0.0.1)", flush=True)


def thumbnails(images: np.ndarray | list, side: int = THUMB) -> list[np.ndarray]:
    """uint8 thumbnails (striding, longest side <= side) of float or uint8 images [H, W, 3]."""
    out = []
    for img in images:
        step = max(1, int(np.ceil(max(img.shape[:2]) / side)))
        small = np.asarray(img[::step, ::step, :3])
        out.append(small if small.dtype == np.uint8 else to_uint8(small))
    return out


def _photo_thumbnails(data_dir: Path, names: list[str]) -> list[np.ndarray] | None:
    out = []
    for name in names:
        path = Path(name) if Path(name).is_absolute() else data_dir / name
        try:
            with Image.open(path) as im:
                im.thumbnail((THUMB, THUMB))
                out.append(np.asarray(im.convert("RGB")))
        except OSError:
            return None  # photos moved away: frustums without pictures
    return out


def scene_view_of_run(run_dir: Path, cfg, params: dict | None = None) -> SceneView:
    """Training cameras (with thumbnails when the photos are still where the run found them), box, background;
    the cameras at their refined poses where the run's params learned pose corrections (--pose-refine)."""
    scene = RunFolder(run_dir).scene()
    poses = np.asarray(run_poses(params, scene["train_poses"]), np.float64)
    cams = [Camera.from_json(scene["camera"])] * len(poses)
    thumbs = None
    d = cfg.data
    try:
        cap = read_capture(Path(scene["data_dir"]), d.train_split, d.format, d.masks, d.holdout_every)
        sel = scene_cameras(cap, d.train_split, d.downscale, d.target_width, d.undistort)
        if len(sel.cameras) == len(poses):
            cams = sel.cameras
            thumbs = _photo_thumbnails(cap.root, sel.names)
    except (DataError, OSError):
        pass
    return scene_view(poses, cams, thumbs, cfg)


def scene_view(poses: np.ndarray, cameras: list, thumbs: list | None, cfg) -> SceneView:
    """Cameras plus what the config says of the scene: its box (bounded) or the contraction's unit ball."""
    f = cfg.field
    return SceneView(poses, cameras, thumbs, bound=1.0 if f.unbounded() else f.resolved_bound(),
                     unbounded=f.unbounded(), background=background_rgb(cfg.data.background))


def view_run(run_dir: Path, host: str = "127.0.0.1", port: int = 7007, chunk: int | None = None) -> None:
    """`nerfkit view RUN`: serve the newest checkpoint of a run until Ctrl-C."""
    run_dir = Path(run_dir)
    check_address(host, port)
    check_chunk(chunk)
    trained = RunFolder(run_dir).load(scene=False)
    cfg, model, params, aux, step = trained.cfg, trained.model, trained.params, trained.aux, trained.step
    viewer = Viewer(make_renderer(model, cfg.train.chunk if chunk is None else chunk), scene_view_of_run(run_dir, cfg, params),
                    run_dir, host=host, port=port, splats=model.supports.gaussians)
    viewer.set_params(params, aux, step)
    try:
        serve_until_interrupted(viewer, f"viewer for {run_dir} (step {step}) at {viewer.url}  (Ctrl-C to stop)")
    finally:
        viewer.close()


def serve_until_interrupted(viewer: Viewer, message: str) -> None:
    """Print `message` (the address, "Ctrl-C to stop"), then render frames until Ctrl-C (SIGINT), then say so
    (the caller closes the viewer). The handler is in place before the message appears, so a Ctrl-C right
    after it stops cleanly. SIGINT (and SIGTERM) raise KeyboardInterrupt here even when the process started
    with SIGINT ignored (a background job of a script), and one that lands in a gc callback while a frame
    renders is raised again rather than dropped (core/interrupts.py)."""
    try:
        with interrupts_raise():
            print(message, flush=True)
            viewer.serve_forever()
    except KeyboardInterrupt:
        print("\nviewer stopped", flush=True)


# The viewer's share of wall time while training (the ceiling for all of its cost: 10%).
TRAINING_FRACTION = 0.04


@dataclass
class LiveView(Callback):
    """The training loop's callback for a viewer (training/callbacks.py): the parameters it starts from, then after
    every step the new ones, and a render when the viewer's duty-cycle gate is open."""

    viewer: Viewer

    def begin(self, trainer, loop, state) -> None:
        self.viewer.set_params(state["params"], state["aux"], loop.step)

    def after_step(self, trainer, loop, state) -> None:
        self.viewer.set_params(state["params"], state["aux"], loop.step)
        self.viewer.render_pending()


def attach_viewer(trainer, host: str = "127.0.0.1", port: int = 7007) -> Viewer:
    """Serve a Trainer's live parameters between its steps (a LiveView in trainer.callbacks). The caller checks
    host and port first (check_address), before the data loads."""
    td = trainer.train_data
    scene = scene_view(td.poses, td.cameras, thumbnails([td.image(k) for k in range(len(td))]), trainer.cfg)
    # Training cameras start hidden (one click shows them): drawn with their photos, they cost a headless
    # or GPU-less browser on the same 2 cores 0.19 cores, against 0.02 hidden (measured on lego).
    viewer = Viewer(trainer.renderer, scene, trainer.run_dir, host=host, port=port, max_fraction=TRAINING_FRACTION,
                    show_cameras=False, splats=trainer.model.supports.gaussians)
    trainer.callbacks.append(LiveView(viewer))
    print(f"viewer at {viewer.url} (live while training)", flush=True)
    return viewer


def linger(viewer: Viewer) -> None:
    """After training: keep the viewer open on the final parameters until Ctrl-C."""
    viewer.max_fraction = 1.0
    serve_until_interrupted(viewer, f"training finished; the viewer stays open at {viewer.url} (Ctrl-C to stop)")
