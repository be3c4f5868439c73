"""A splat run's exported .ply in a third-party renderer: viser's Gaussian splats in headless Chromium.

    python benchmarks/splat_third_party.py RUN [--name lego] [--views 0 30] [--size 400]

Runs what a user types, `nerfkit export splat RUN --out OUT.ply` (timed), reads the file back with plyfile
(import_ply: the capture's own coordinates) and has viser draw it in headless Chromium (tests/viser_splats.py)
from training cameras of the run, moved into the capture's frame; nerfkit's rasteriser renders the same file
from the same cameras (degree-0 colour, which is what viser draws). Writes benchmarks/results/
splat_<name>_viser.png (per view: nerfkit | viser) and splat_<name>_viser.json (PSNR between the two).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--name", default=None)
    ap.add_argument("--views", type=int, nargs="+", default=[0, 30])
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    import imageio.v3 as iio
    from chromium import find_chromium
    from viser_splats import viser_render

    from nerfkit.core.metrics import psnr
    from nerfkit.evaluation.evaluate import capture_poses
    from nerfkit.models.splat.gaussians import render
    from nerfkit.models.splat.formats.ply import import_ply
    from nerfkit.rays.cameras import Camera

    chromium = find_chromium()
    if chromium is None:
        sys.exit("no Chromium found: apt-get install chromium (or set NERFKIT_CHROMIUM)")
    name = a.name or a.run.name
    sc = json.loads((a.run / "scene.json").read_text())
    frame = SimpleNamespace(transform=np.asarray(sc.get("transform", np.eye(4)), np.float64),
                            scale=float(sc.get("scale", 1.0)))  # x_n = M x_c, M's rotation part scaled by `scale`
    fov = 2 * np.arctan(0.5 * sc["height"] / Camera.from_json(sc["camera"]).fy)
    rows, out = [], {"provenance": provenance(), "run": str(a.run), "renderer": "viser add_gaussian_splats",
                     "colour": "degree 0 (SH_C0 f_dc + 0.5) in both", "views": []}
    with tempfile.TemporaryDirectory() as tmp:
        ply = Path(tmp) / "scene.ply"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "nerfkit", "export", "splat", str(a.run), "--out", str(ply)], check=True,
                       stdout=subprocess.DEVNULL)
        out["export_seconds"] = round(time.perf_counter() - t0, 1)
        g = import_ply(ply)
        out["gaussians"] = len(g["means"])
        for k in a.views:
            pose = np.asarray(capture_poses(frame, [np.asarray(sc["train_poses"][k], np.float64)])[0])
            got, cam = viser_render(chromium, Path(tmp) / f"profile{k}", g, pose, fov, a.size)
            want = np.clip(render(g, pose, cam, sh_degree=0)["rgb"], 0.0, 1.0)
            score = float(psnr(got, want))
            out["views"].append({"train_view": k, "width": cam.width, "height": cam.height,
                                 "psnr_viser_vs_nerfkit": score})
            print(f"view {k}: viser vs nerfkit {score:.2f} dB at {cam.width}x{cam.height}")
            rows.append(np.concatenate([want, got], 1))
    a.results.mkdir(parents=True, exist_ok=True)
    iio.imwrite(a.results / f"splat_{name}_viser.png", (np.concatenate(rows, 0) * 255).astype(np.uint8))
    (a.results / f"splat_{name}_viser.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {a.results / f'splat_{name}_viser.json'}")


if __name__ == "__main__":
    main()
