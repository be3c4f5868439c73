"""Collect `nerfkit eval` records of several runs into one results file (for figures quoted from runs made by hand).

    python benchmarks/collect_evals.py LABEL=RUN[:SPLIT] ... --name NAME

For each run, reads RUN/eval_<split>.json (SPLIT as given to `nerfkit eval --split`, default test) and keeps its
PSNR, SSIM, step and view count with the run's training command (config.json's settings that differ from the
preset are not repeated: the run folder is named). Writes benchmarks/results/NAME.json with the commit.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--name", required=True)
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    out = {"provenance": provenance(), "runs": {}}
    for entry in a.runs:
        label, _, rest = entry.partition("=")
        run, _, split = rest.partition(":")
        split = split or "test"
        rec = json.loads((Path(run) / f"eval_{re.sub(r'[^A-Za-z0-9]+', '_', split).strip('_')}.json").read_text())
        cfg = json.loads((Path(run) / "config.json").read_text())
        splat = cfg.get("splat", {})
        out["runs"][label] = {"run": run, "split": split, "psnr": rec["psnr"], "ssim": rec["ssim"], "step": rec["step"],
                              "views": rec.get("n_views"), "random_background": splat.get("random_background"),
                              "normal_consistency": splat.get("normal_consistency", 0.0),
                              "normal_consistency_from": splat.get("normal_consistency_from", 0.0),
                              "depth_distortion": splat.get("depth_distortion", 0.0),
                              "screen_dilation": splat.get("screen_dilation", 0.3),
                              "max_minutes": cfg["train"]["max_minutes"]}
        print(f"{label}: {rec['psnr']:.2f} dB, SSIM {rec['ssim']:.4f} at step {rec['step']}")
    a.results.mkdir(parents=True, exist_ok=True)
    (a.results / f"{a.name}.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
