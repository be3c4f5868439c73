"""Lego through the command line, as a user runs it: PSNR against the CLI's own wall clock.

    python benchmarks/lego_cli.py [--data LEGO] [--preset ngp] [--minutes 2 5 10] [--out runs/lego_cli]
                                  [--target-width 200] [--train-args "--backend numba"]

For each budget M, one fresh run of exactly what a user types (seed protocol, 200x200; --target-width 400 is
the shared data's own resolution, written to lego_cli_<preset>_400.json):

    nerfkit train LEGO --out OUT/<preset>_<M>min --preset P --train-split "train,val[0:50]"
                       --val-split "val[50:100]" --target-width 200 --max-minutes M
    nerfkit eval OUT/<preset>_<M>min --split "val[50:100]"

The wall clock is the whole `nerfkit train` process (start-up, data loading, compilation, periodic
validation and the final validation, checkpoints and the report included); the PSNR and SSIM are
`nerfkit eval`'s over all 50 views. Writes benchmarks/results/lego_cli_<preset>.json (with the commit it
ran on) and a plot of PSNR against minutes.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
from pathlib import Path

from clirun import nerfkit
from provenance import provenance

from nerfkit.core.viz import plot_curves, read_jsonl

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "nerf_synthetic" / "lego"
SEED = ["--train-split", "train,val[0:50]", "--val-split", "val[50:100]", "--target-width", "200"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--preset", default="ngp")
    ap.add_argument("--minutes", type=float, nargs="+", default=[2.0, 5.0, 10.0])
    ap.add_argument("--out", type=Path, default=Path("runs/lego_cli"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    ap.add_argument("--target-width", type=int, default=200)
    ap.add_argument("--train-args", default="", help="more arguments for nerfkit train (one string)")
    a = ap.parse_args()
    width = a.target_width
    suffix = "" if width == 200 else f"_{width}"
    rows = []
    for minutes in a.minutes:
        run = a.out / f"{a.preset}{suffix}_{minutes:g}min"
        train_s, out = nerfkit("train", str(a.data), "--out", str(run), "--preset", a.preset, *SEED[:-1],
                               str(width), *shlex.split(a.train_args),
                               "--max-minutes", f"{minutes:g}", "--no-progress", "--overwrite")
        eval_s, _ = nerfkit("eval", str(run), "--split", "val[50:100]", "--overwrite")
        ev = json.loads((run / "eval_val_50_100.json").read_text())
        m = re.search(r"step (\d+), ([\d.]+) steps/s", out)
        vrows = read_jsonl(run / "val_metrics.jsonl")
        row = {"budget_minutes": minutes, "train_wall_s": round(train_s, 1), "steps": int(m.group(1)) if m else None,
               "steps_per_second_cli": float(m.group(2)) if m else None, "psnr": round(ev["psnr"], 3),
               "ssim": round(ev["ssim"], 4), "views": ev["n_views"], "eval_wall_s": round(eval_s, 1),
               "validation_curve": [{"step": r["step"], "elapsed_s": r["elapsed"], "psnr": round(r["psnr"], 3),
                                     "views": len(r["views"])} for r in vrows]}
        rows.append(row)
        print(f"{a.preset} {minutes:g} min: {row['steps']} steps in {train_s / 60:.2f} min of wall clock, "
              f"{ev['psnr']:.2f} dB / SSIM {ev['ssim']:.4f} on all {ev['n_views']} views of val[50:100]", flush=True)
    result = {"what": f"nerfkit train + nerfkit eval on lego (seed protocol, {width}x{width}), wall clock of the CLI",
              "data": str(a.data), "preset": a.preset, "target_width": width, "train_args": a.train_args, "runs": rows, "provenance": provenance()}
    a.results.mkdir(parents=True, exist_ok=True)
    path = a.results / f"lego_cli_{a.preset}{suffix}.json"
    path.write_text(json.dumps(result, indent=2))
    plot_curves({a.preset: ([r["train_wall_s"] / 60 for r in rows], [r["psnr"] for r in rows])},
                path.with_suffix(".png"), "wall clock of nerfkit train (min)", "PSNR on val[50:100] (dB)",
                f"lego {width}x{width}, seed protocol: {a.preset}")
    print(f"wrote {path} and {path.with_suffix('.png')}")


if __name__ == "__main__":
    main()
