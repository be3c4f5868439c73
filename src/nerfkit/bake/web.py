"""A baked scene's web page: the static WebGL2 viewer (web/) and a small server for it.

The viewer is three static files, web/index.html, web/render.js (loading, textures, the
ray-marching shader) and web/baked.js (the page: orbit controls, frame time, test API), with no
build step and no network access: the page fetches baked.json and the three .npy arrays from
its own folder and ray-marches them in a fragment shader exactly as the reference renderer
(models/baked/model.py) does (see render.js for the texture layout and the marching). `write_web` copies the page into a baked
scene folder, which any static file server can then serve (python -m http.server).

`nerfkit view --baked DIR` calls `serve_baked`: the folder must be a baked scene (baked.json of
format.FORMAT); the page is written beside it when missing (and served from the package when
the folder is read-only); the stdlib's threading HTTP server serves the folder on 127.0.0.1 by
default, on the next free port when the one asked for is taken, until Ctrl-C. `start_server` /
`stop_server` are the same server without the waiting, for tests and scripts.
"""

from __future__ import annotations

import json
import shutil
import socket
import threading
import time
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from nerfkit.core.errors import ConfigError
from nerfkit.models.baked.format import FORMAT
from nerfkit.viewer.run import check_host, check_port, is_loopback

WEB_DIR = Path(__file__).parent / "web"
ASSETS = ("index.html", "render.js", "baked.js")
ARRAYS = ("index.npy", "density.npy", "sh.npy")
PORT_TRIES = 20


def write_web(out: Path) -> None:
    """Copy the viewer page (ASSETS) into the baked scene folder `out`."""
    out = Path(out)
    for name in ASSETS:
        shutil.copyfile(WEB_DIR / name, out / name)


def check_baked(baked_dir: Path) -> dict:
    """baked.json of a baked scene folder; ConfigError (one line) when the folder is not one."""
    baked_dir = Path(baked_dir)
    fix = f"make one with nerfkit bake RUN --out {baked_dir}"
    if not baked_dir.is_dir():
        raise ConfigError(f"{baked_dir}: no such folder; a baked scene is a folder: {fix}")
    if (baked_dir / "splats.json").is_file() and (baked_dir / "splats.bin").is_file():  # a splat run's page
        try:
            return json.loads((baked_dir / "splats.json").read_text())
        except (OSError, ValueError):
            raise ConfigError(f"{baked_dir / 'splats.json'}: unreadable; bake it again: {fix}") from None
    try:
        meta = json.loads((baked_dir / "baked.json").read_text())
    except (OSError, ValueError):
        raise ConfigError(f"{baked_dir}: not a baked scene (no readable baked.json); {fix}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        got = meta.get("format") if isinstance(meta, dict) else None
        raise ConfigError(f"{baked_dir / 'baked.json'}: format {got!r}, expected {FORMAT!r}; bake it again: {fix}")
    missing = [n for n in ARRAYS if not (baked_dir / n).is_file()]
    if missing:
        raise ConfigError(f"{baked_dir}: baked scene without {', '.join(missing)}; bake it again: {fix}")
    return meta


def scene_mb(baked_dir: Path) -> float:
    """Size of the scene's arrays (what the page downloads, besides itself) in MB (2^20 bytes)."""
    return sum(p.stat().st_size for n in (*ARRAYS, "splats.bin") if (p := Path(baked_dir) / n).is_file()) / 2**20


class _Handler(SimpleHTTPRequestHandler):
    """Static files of one folder, quietly; the page's assets from the package when the folder lacks them
    (or always, with package_page)."""

    package_page = False
    extensions_map = {**SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript",
                      ".npy": "application/octet-stream", ".json": "application/json"}

    def translate_path(self, path: str) -> str:
        local = super().translate_path(path)
        root = Path(self.directory)
        asset = root / "index.html" if Path(local) == root else Path(local)
        if asset.parent == root and asset.name in ASSETS and (self.package_page or not asset.exists()):
            return str(WEB_DIR / asset.name)
        return local

    def end_headers(self):
        self.send_header("Cache-Control", "no-cache")  # a re-baked scene must not show stale arrays
        super().end_headers()

    def log_message(self, *args):  # no line per request
        pass


def _server_class(host: str):
    """ThreadingHTTPServer for IPv4 or IPv6 `host`."""
    if ":" not in host:
        return ThreadingHTTPServer
    return type("ThreadingHTTPServer6", (ThreadingHTTPServer,), {"address_family": socket.AF_INET6})


def bind(baked_dir: Path, host: str, port: int, package_page: bool = False) -> ThreadingHTTPServer:
    """An HTTP server of the folder bound to host:port, or the next free port of PORT_TRIES (port 0: any);
    package_page: serve the page's assets from the package even where the folder has its own."""
    cls = type("BakedHandler", (_Handler,), {"package_page": package_page})
    handler = partial(cls, directory=str(Path(baked_dir).resolve()))
    server_cls = _server_class(host)
    tries = [0] if port == 0 else range(port, min(port + PORT_TRIES, 65536))
    last = None
    for p in tries:
        try:
            return server_cls((host, p), handler)
        except OSError as e:
            last = e
    raise ConfigError(f"cannot listen on {host} ports {port}..{port + PORT_TRIES - 1} ({last}); pass another --port")


def start_server(baked_dir: Path, host: str = "127.0.0.1", port: int = 0, write_page: bool = True):
    """Serve a baked scene folder in a background thread; returns (server, url of the page).

    write_page: write the page into the folder when it has none (a read-only folder gets the package's
    page served instead); False leaves the folder untouched and always serves the package's page."""
    baked_dir = Path(baked_dir)
    check_baked(baked_dir)
    if write_page and not (baked_dir / "index.html").exists() and not (baked_dir / "splats.json").exists():
        try:
            write_web(baked_dir)
        except OSError:
            pass  # read-only folder: the handler serves the page from the package
    server = bind(baked_dir, host, port, package_page=not write_page)
    threading.Thread(target=server.serve_forever, args=(0.1,), name="nerfkit-baked-http", daemon=True).start()
    shown = "127.0.0.1" if host in ("0.0.0.0", "") else ("localhost" if host == "::" else host)
    shown = f"[{shown}]" if ":" in shown else shown
    return server, f"http://{shown}:{server.server_address[1]}/"


def stop_server(server: ThreadingHTTPServer) -> None:
    """Stop serving and close the socket."""
    server.shutdown()
    server.server_close()


def serve_baked(baked_dir: Path, host: str = "127.0.0.1", port: int = 7007) -> None:
    """`nerfkit view --baked DIR`: serve the scene's page until Ctrl-C, printing its address and size."""
    check_port(port)
    check_host(host)
    server, url = start_server(baked_dir, host, port)
    print(f"serving the baked scene {baked_dir} ({scene_mb(baked_dir):.1f} MB) at {url} (Ctrl-C stops)", flush=True)
    if not is_loopback(host):
        print(f"warning: listening on {host}: anyone who can reach this machine can load the scene", flush=True)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        print("stopped", flush=True)
    finally:
        stop_server(server)
