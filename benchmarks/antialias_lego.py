"""Rays against cones on multiscale lego, at one wall-clock budget per model (docs/aliasing.md's table).

    python benchmarks/antialias_lego.py [--ms runs/multiscale/lego_ms] [--out runs/antialias] [--minutes 6]

Runs exactly what docs/aliasing.md shows a user:

    nerfkit experiment antialias MS --out OUT --budget-minutes 6 --eval-every 10 \
        --train-split "train,val[0:50]" --val-split "val[50:100]"

(MS: `nerfkit make-multiscale` of the shared 400 px lego, made here when missing), then copies the
experiment's results.json, with this run's provenance, to benchmarks/results/antialias_lego.json and its
crops of the first val view to antialias_lego_crops.png. The budget is wall time: run it on an idle machine.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from lego_cli import DEFAULT_DATA, ROOT, nerfkit
from provenance import provenance


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the 400 px lego (made multiscale when --ms is missing)")
    ap.add_argument("--ms", type=Path, default=Path("runs/multiscale/lego_ms"))
    ap.add_argument("--out", type=Path, default=Path("runs/antialias"))
    ap.add_argument("--minutes", type=float, default=6.0)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    prov = provenance()
    if not (a.ms / "metadata.json").is_file():
        nerfkit("make-multiscale", str(a.data), "--out", str(a.ms))
    if a.out.exists():
        shutil.rmtree(a.out)
    wall, _ = nerfkit("experiment", "antialias", str(a.ms), "--out", str(a.out), "--budget-minutes", f"{a.minutes:g}",
                      "--eval-every", "10", "--train-split", "train,val[0:50]", "--val-split", "val[50:100]")
    res = json.loads((a.out / "results.json").read_text())
    res["provenance"] = prov
    res["experiment_wall_s"] = round(wall, 1)
    res["machine"] = "2 CPU cores, no GPU, the four models one after another"
    path = a.results / "antialias_lego.json"
    path.write_text(json.dumps(res, indent=2))
    shutil.copyfile(a.out / res["grids"][0]["crops"], a.results / "antialias_lego_crops.png")
    for m in res["models"]:
        print(f"{m['label']}: {m['steps']} steps, " + " / ".join(f"{s['psnr']:.2f}" for s in m["scales"])
              + f", mean {m['psnr']:.2f} dB")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
