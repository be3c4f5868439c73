"""Lego at four scales: how a field trained at one resolution scores at the others.

    python benchmarks/multiscale_lego.py [--data LEGO] [--out runs/multiscale] [--keep-lego-run]

Through the CLI, as a user runs it:

    nerfkit make-multiscale LEGO --out OUT/lego_ms                     (skipped if it exists)
    1. nerfkit train LEGO --preset ngp --max-minutes 10, seed protocol at 200 px (lego_cli.SEED)
    2. nerfkit train OUT/lego_ms --preset ngp --max-minutes 4 --train-split "train_d0,val_d0[0:50]"
    3. nerfkit train OUT/lego_ms --preset ngp --max-minutes 4 --train-split "train,val[0:50]" (all four scales)
    nerfkit eval RUN --data OUT/lego_ms --split "val[50:100]"          (every level at its own size)

Writes benchmarks/results/multiscale_lego.json (per model: steps, PSNR / SSIM per scale and their mean,
the training wall clock; with provenance). Run 1 stays in OUT/ngp_10min_200px: benchmarks/bake_quality.py
bakes it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lego_cli import DEFAULT_DATA, ROOT, SEED, nerfkit
from provenance import provenance

VAL = "val[50:100]"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--out", type=Path, default=Path("runs/multiscale"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    ms = a.out / "lego_ms"
    if not (ms / "metadata.json").is_file():
        nerfkit("make-multiscale", str(a.data), "--out", str(ms))
    models = {
        "ngp_10min_200px": (a.data, "10", SEED),
        "ngp_4min_400px": (ms, "4", ["--train-split", "train_d0,val_d0[0:50]", "--val-split", "val_d0[50:100]"]),
        "ngp_4min_all_scales": (ms, "4", ["--train-split", "train,val[0:50]", "--val-split", "val_d1[50:100]"]),
    }
    result = {"what": "ngp runs through the CLI scored at every scale of lego made multiscale from the 400 px copy",
              "data": str(a.data), "split": VAL, "provenance": provenance()}
    for key, (data, minutes, flags) in models.items():
        run = a.out / key
        train_s, _ = nerfkit("train", str(data), "--out", str(run), "--preset", "ngp", *flags, "--max-minutes", minutes,
                             "--no-progress", "--overwrite")
        nerfkit("eval", str(run), "--data", str(ms), "--split", VAL, "--overwrite")
        ev = json.loads((run / "eval_val_50_100_multiscale.json").read_text())
        result[key] = {"run": str(run), "train_flags": flags, "max_minutes": float(minutes),
                       "train_wall_s": round(train_s, 1), "step": ev["step"], "split": VAL,
                       "mean_psnr": ev["psnr"], "mean_ssim": ev["ssim"],
                       "scales": [{"level": s["level"], "width": s["width"], "psnr": s["psnr"], "ssim": s["ssim"],
                                   "n_views": s["n_views"]} for s in ev["scales"]]}
        print(f"{key}: step {ev['step']}, " + " / ".join(f"{s['width']} px {s['psnr']:.2f}" for s in ev["scales"])
              + f", mean {ev['psnr']:.2f} dB", flush=True)
    path = a.results / "multiscale_lego.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
