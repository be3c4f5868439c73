"""A trained scene's splat files drawn by third-party web renderers in headless Chromium: Spark (.ply, .spz,
.splat) and the PlayCanvas engine (.glb, which Spark does not read, and .sog, PlayCanvas's own format).

    python benchmarks/splat_spark.py FOLDER [--name lego] [--views 0 30] [--size 400]

FOLDER is what benchmarks/splat_formats.py leaves for a scene (FOLDER/run, the run; FOLDER/scene.EXT, the files
`nerfkit export splat` wrote). Each of scene.ply, scene.spz and scene.splat is drawn by Spark (npm
@sparkjsdev/spark, pinned in tests/web; tests/spark_splats.py: a loopback page, nothing from the network) from
training cameras of the run, moved into the capture's frame, and nerfkit's rasteriser draws the same file as it
reads it back from the same camera: PSNR between the two, with Spark set to nerfkit's kernel (preBlurAmount 0.3,
maxStdDev 3, z-sorted) and with Spark's own defaults (what a page gets). scene.glb and scene.sog are drawn by
PlayCanvas (npm playcanvas, pinned in tests/web; tests/playcanvas_splats.py) with its defaults. Writes
benchmarks/results/splat_<name>_spark.json and splat_<name>_spark.png (per format and view: nerfkit | renderer).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests")]
FORMATS = ("ply", "spz", "splat")  # Spark's
PLAYCANVAS_FORMATS = ("glb", "sog")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--name", default=None)
    ap.add_argument("--views", type=int, nargs="+", default=[0, 30])
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    import imageio.v3 as iio
    from chromium import find_chromium
    from playcanvas_splats import PlayCanvasPage, playcanvas_vs_nerfkit
    from spark_splats import SparkPage, spark_vs_nerfkit, training_view

    chromium = find_chromium()
    if chromium is None:
        sys.exit("no Chromium found: apt-get install chromium (or set NERFKIT_CHROMIUM)")
    name = a.name or a.folder.name
    out = {"provenance": provenance(), "folder": str(a.folder),
           "renderer": "Spark 2.2.0 (three.js 0.187.0); .glb and .sog: the PlayCanvas engine 2.23.3",
           "size": a.size, "formats": {}}
    rows = []
    with tempfile.TemporaryDirectory() as tmp, SparkPage(chromium, Path(tmp) / "profile", (a.size, a.size)) as page:
        for fmt in FORMATS:
            file = a.folder / f"scene.{fmt}"
            views = []
            for k in a.views:
                c2w, cam = training_view(a.folder / "run", k, a.size)
                matched = spark_vs_nerfkit(page, file, c2w, cam)
                default = spark_vs_nerfkit(page, file, c2w, cam, options={})
                views.append({"train_view": k, "width": cam.width, "height": cam.height,
                              "psnr_spark_vs_nerfkit": round(matched["psnr"], 2),
                              "psnr_spark_defaults_vs_nerfkit": round(default["psnr"], 2)})
                print(f"{fmt} view {k}: Spark vs nerfkit {matched['psnr']:.2f} dB (Spark's defaults "
                      f"{default['psnr']:.2f}) at {cam.width}x{cam.height}", flush=True)
                rows.append(np.concatenate([matched["nerfkit"], matched["spark"]], 1))
            out["formats"][fmt] = {"bytes": file.stat().st_size, "views": views}
    with tempfile.TemporaryDirectory() as tmp, PlayCanvasPage(chromium, Path(tmp) / "profile", (a.size, a.size)) as page:
        for fmt in PLAYCANVAS_FORMATS:
            file, views = a.folder / f"scene.{fmt}", []
            for k in a.views:
                c2w, cam = training_view(a.folder / "run", k, a.size)
                got = playcanvas_vs_nerfkit(page, file, c2w, cam)
                views.append({"train_view": k, "width": cam.width, "height": cam.height,
                              "psnr_playcanvas_vs_nerfkit": round(got["psnr"], 2)})
                print(f"{fmt} view {k}: PlayCanvas vs nerfkit {got['psnr']:.2f} dB at {cam.width}x{cam.height}",
                      flush=True)
                rows.append(np.concatenate([got["nerfkit"], got["playcanvas"]], 1))
            out["formats"][fmt] = {"bytes": file.stat().st_size, "renderer": "PlayCanvas 2.23.3", "views": views}
    a.results.mkdir(parents=True, exist_ok=True)
    iio.imwrite(a.results / f"splat_{name}_spark.png", np.round(np.concatenate(rows, 0) * 255).astype(np.uint8))
    (a.results / f"splat_{name}_spark.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {a.results / f'splat_{name}_spark.json'}")


if __name__ == "__main__":
    main()
