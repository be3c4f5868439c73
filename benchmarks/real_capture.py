"""A real capture end to end: poses from SfM vs the shipped poses, then PSNR against time.

    python benchmarks/real_capture.py [--data ../shared/data/real/maryrose] [--minutes 10] [--out runs/real]

1. `nerfkit process-data images DATA/images --masks DATA/masks --out OUT/sfm` (skipped if OUT/sfm
   exists): registered photos, time, and the agreement of its cameras with DATA's poses
   (Umeyama alignment of the centres; centre error / radius, rotation error).
2. Two runs of exactly what a user types, on the shipped LLFF poses and on the SfM output:
   `nerfkit train X --preset ngp --max-minutes M --downscale 2 --out OUT/run_*` (checkpoints
   every --ckpt-every steps are kept), then `nerfkit eval RUN --split test`.
3. Every kept checkpoint is evaluated on all held-out photos afterwards, so the PSNR-against-
   training-time curve costs the runs nothing; the table, benchmarks/results/<capture>_real_capture.json
   (with the commit it ran on) and its .png hold it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from provenance import provenance

from nerfkit.core.viz import plot_curves
from nerfkit.data.formats.llff import read_llff
from nerfkit.data.loader import read_capture
from nerfkit.evaluation.evaluate import evaluate_run
from nerfkit.process.align import pose_errors
from nerfkit.training import checkpoint as ckpt_lib

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "maryrose"


def nerfkit(*args: str) -> float:
    """Run the CLI (as a user would), return its wall time."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "nerfkit", *args], check=True)
    return time.perf_counter() - t0


def curve(run: Path) -> list[dict]:
    """Test PSNR / SSIM of every checkpoint of a run, against its training time."""
    rows = []
    for path in ckpt_lib.list_checkpoints(run / "checkpoints"):
        elapsed = float(ckpt_lib.read_checkpoint(path)["state"]["elapsed"])
        ev = evaluate_run(run, None, "test", progress=False, checkpoint=path, write=False)
        rows.append({"step": ev["step"], "minutes": round(elapsed / 60, 2), "psnr": round(ev["psnr"], 3),
                     "ssim": round(ev["ssim"], 4)})
        print(f"  {run.name}: step {ev['step']:5d}  {elapsed / 60:5.2f} min  test PSNR {ev['psnr']:.2f} dB  "
              f"SSIM {ev['ssim']:.4f}", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--out", type=Path, default=Path("runs/real_capture"))
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--downscale", type=int, default=2)
    ap.add_argument("--ckpt-every", type=int, default=250)
    ap.add_argument("--results", type=Path, default=Path(__file__).resolve().parent / "results")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    result = {"data": str(a.data), "minutes": a.minutes, "downscale": a.downscale, "provenance": provenance()}

    sfm = a.out / "sfm"
    if not sfm.is_dir():
        result["sfm_seconds"] = nerfkit("process-data", "images", str(a.data / "images"), "--masks",
                                        str(a.data / "masks"), "--out", str(sfm))
    proc = json.loads((sfm / "process.json").read_text())
    ref = {f.image.name: f.c2w for f in read_llff(a.data, masks=False).splits["all"]}
    got = {f.image.name: f.c2w for f in read_capture(sfm, "all").splits["all"]}
    names = sorted(got)
    err = pose_errors(np.stack([got[n] for n in names]), np.stack([ref[n] for n in names]))
    result["sfm"] = {"registered": proc["registered"], "photos": proc["photos"], "seconds": proc["seconds"],
                     "pose_errors": err}
    print(f"SfM: {proc['registered']}/{proc['photos']} photos registered in {proc['seconds']['total'] / 60:.1f} min; "
          f"centre error median {100 * err['centre_median']:.2f}% / max {100 * err['centre_max']:.2f}% of the radius, "
          f"rotation error median {err['rotation_median_deg']:.2f} / max {err['rotation_max_deg']:.2f} deg")

    runs = {"shipped poses (LLFF)": (a.data, a.out / "run_llff"), "process-data poses": (sfm, a.out / "run_sfm")}
    for label, (data, run) in runs.items():
        if not (run / "eval_test.json").is_file():
            result[f"{label} train_wall_s"] = round(nerfkit(
                "train", str(data), "--out", str(run), "--preset", "ngp", "--max-minutes", str(a.minutes),
                "--downscale", str(a.downscale), "--ckpt-every", str(a.ckpt_every), "--keep-ckpts", "1000",
                "--overwrite", "--no-progress"), 1)
            nerfkit("eval", str(run), "--split", "test", "--overwrite")
        ev = json.loads((run / "eval_test.json").read_text())
        result[label] = {"run": str(run), "eval": {k: ev[k] for k in ("psnr", "ssim", "n_views", "step")},
                         "curve": curve(run)}
    print(f"\nPSNR against training time (all {ev['n_views']} held-out photos, every 8th; masks on):")
    labels = list(runs)
    print(f"{'minutes':>8} " + " ".join(f"{lab:>24}" for lab in labels))
    by_label = {lab: {r["step"]: r for r in result[lab]["curve"]} for lab in labels}
    steps = sorted(set().union(*[set(v) for v in by_label.values()]))
    for s in steps:
        cells = [f"{by_label[lab][s]['minutes']:5.2f} min {by_label[lab][s]['psnr']:6.2f} dB" if s in by_label[lab]
                 else "" for lab in labels]
        print(f"{'step ' + str(s):>8} " + " ".join(f"{c:>24}" for c in cells))
    for lab in labels:
        e = result[lab]["eval"]
        print(f"{lab}: nerfkit eval --split test: PSNR {e['psnr']:.2f} dB, SSIM {e['ssim']:.4f} (step {e['step']})")
    diff = result[labels[0]]["eval"]["psnr"] - result[labels[1]]["eval"]["psnr"]
    print(f"difference: {diff:+.2f} dB")
    result["difference_db"] = diff
    a.results.mkdir(parents=True, exist_ok=True)
    path = a.results / f"{a.data.name}_real_capture.json"
    path.write_text(json.dumps(result, indent=2))
    plot_curves({lab: ([r["minutes"] for r in result[lab]["curve"]], [r["psnr"] for r in result[lab]["curve"]])
                 for lab in labels}, path.with_suffix(".png"), "training time (min)", "test PSNR (dB)",
                f"{a.data.name}: ngp, --downscale {a.downscale}, masks")
    print(f"wrote {path} and {path.with_suffix('.png')}")


if __name__ == "__main__":
    main()
