"""A textured GLB in a real browser: headless Chromium (software WebGL2) draws it with the minimal glTF
reader of the tests (tests/export/glb_page.html) from two of the run's training cameras; the screenshots
sit beside the Python rendering of the same file and the field's own render, and the PSNR between the
browser and Python pictures is recorded.

    python benchmarks/glb_screenshot.py RUN GLB [--name lego] [--size 400] [--views 0 30]

Writes benchmarks/results/mesh_<name>_glb.png and mesh_<name>_glb.json.
"""

from __future__ import annotations

import argparse
import base64
import functools
import io
import json
import shutil
import sys
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
from provenance import provenance

from nerfkit.run.folder import RunFolder

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "export")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("glb", type=Path)
    ap.add_argument("--name", default=None)
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--views", type=int, nargs="+", default=[0, 30])
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    import tempfile

    import matplotlib.pyplot as plt
    import test_glb_browser as page
    import trimesh
    from chromium import Chromium, find_chromium
    from PIL import Image

    from nerfkit.core.metrics import psnr
    from nerfkit.data.loader import read_capture, scene_cameras
    from nerfkit.rays.cameras import Camera
    from nerfkit.render.images import make_renderer

    run = RunFolder(a.run).load()
    d = run.cfg.data
    cap = read_capture(RunFolder(a.run).data_dir(None), d.train_split, d.format, d.masks, d.holdout_every)
    sel = scene_cameras(cap, d.train_split)
    inv = np.linalg.inv(run.transform)
    page.W = page.H = a.size
    page.FOCAL = sel.cameras[0].fx * a.size / sel.cameras[0].width
    cam = Camera(a.size, a.size, page.FOCAL, page.FOCAL, a.size / 2, a.size / 2)
    mesh = trimesh.load(a.glb, force="mesh")
    renderer = make_renderer(run.model, run.cfg.train.chunk)
    with tempfile.TemporaryDirectory() as tmp:
        site = Path(tmp) / "site"
        site.mkdir()
        shutil.copy(a.glb, site / "mesh.glb")
        shutil.copy(page.PAGE, site / "index.html")
        server = ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(SimpleHTTPRequestHandler, directory=str(site)))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        browser = Chromium(find_chromium(), Path(tmp) / "profile", a.size, a.size, webgl=True)
        rows = []
        try:
            browser.open_page()
            for k in a.views:
                c2w_n = sel.poses[k].astype(np.float64)
                c2w = inv @ c2w_n  # the GLB is in the capture's coordinates
                c2w[:3, :3] /= np.cbrt(np.linalg.det(c2w[:3, :3]))  # a rigid camera (undo the normalisation's scale)
                query = f"glb=mesh.glb&w={a.size}&h={a.size}&fx={page.FOCAL}&fy={page.FOCAL}&cx={a.size / 2}" \
                        f"&cy={a.size / 2}&c2w=" + ",".join(f"{v:.9g}" for v in c2w.reshape(-1))
                browser.navigate(f"http://127.0.0.1:{server.server_port}/index.html?{query}")
                result = browser.evaluate("window.result")
                url = browser.evaluate("document.getElementById('c').toDataURL('image/png')")
                shot = np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB")) / 255
                ref = page.python_render(mesh, c2w)
                field = renderer.render_camera(run.params, run.aux, c2w_n.astype(np.float32), cam)["rgb"]
                rows.append({"view": k, "triangles": result.get("triangles"), "psnr_browser_vs_python": psnr(shot, ref),
                             "images": (shot, ref, np.clip(field, 0, 1))})
        finally:
            browser.close()
            server.shutdown()
    name = a.name or a.run.name
    fig, axes = plt.subplots(len(rows), 3, figsize=(12, 4 * len(rows)), squeeze=False)
    for r, row in enumerate(rows):
        for c, (img, title) in enumerate(zip(row["images"], ("Chromium (WebGL2) reading the GLB",
                                                             "Python rendering of the GLB", "the field"))):
            axes[r, c].imshow(img)
            axes[r, c].set_title(f"view {row['view']}: {title}", fontsize=9)
            axes[r, c].axis("off")
    fig.tight_layout()
    a.results.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.results / f"mesh_{name}_glb.png", dpi=70)
    out = {"provenance": provenance(), "glb": str(a.glb), "faces": len(mesh.faces),
           "views": [{k: v for k, v in r.items() if k != "images"} for r in rows]}
    (a.results / f"mesh_{name}_glb.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out["views"]))


if __name__ == "__main__":
    main()
