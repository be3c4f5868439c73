"""What baking costs and keeps: a field against its bake, on lego and on maryrose (docs/verbs/bake.md's table).

    python benchmarks/bake_quality.py [--lego-run runs/multiscale/ngp_10min_200px] [--out runs/bake]

Through the CLI, as a user runs it, for each run:

    nerfkit eval RUN --split S                      the field
    nerfkit bake RUN --out OUT/<scene>              timed (2 minutes of fine-tuning, the default)
    nerfkit eval RUN --split S --baked OUT/<scene>  the bake

lego: a 10-minute ngp run of the seed protocol (benchmarks/multiscale_lego.py leaves one; made here with
`nerfkit train LEGO --preset ngp --max-minutes 10` and lego_cli.SEED when missing), S = val[50:100], plus a
bake without fine-tuning scored on every 5th view. maryrose: `nerfkit train MARYROSE --preset ngp --max-minutes 6
--downscale 2` (masks on, every 8th photo held out), S = test. Writes benchmarks/results/bake_quality.json
(with provenance); benchmarks/bake_web_frametime.py then times the lego bake in Chromium.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lego_cli import DEFAULT_DATA, ROOT, SEED, nerfkit
from provenance import provenance

from nerfkit.bake.web import scene_mb

MARYROSE = ROOT.parent / "shared" / "data" / "real" / "maryrose"


def bake_and_score(run: Path, out: Path, split: str, slug: str) -> dict:
    nerfkit("eval", str(run), "--split", split, "--overwrite")
    field = json.loads((run / f"eval_{slug}.json").read_text())
    bake_s, _ = nerfkit("bake", str(run), "--out", str(out), "--overwrite", "--no-progress")
    nerfkit("eval", str(run), "--split", split, "--baked", str(out), "--overwrite")
    baked = json.loads((run / f"eval_{slug}_baked.json").read_text())
    meta = json.loads((out / "baked.json").read_text())
    return {"run": str(run), "split": split, "step": field["step"], "field_psnr": field["psnr"], "field_ssim": field["ssim"],
            "baked_psnr": baked["psnr"], "baked_ssim": baked["ssim"], "n_views": baked["n_views"],
            "resolution": meta["resolution"], "bricks": meta["bricks"], "sh_bands": meta["sh_bands"],
            "finetune": meta.get("finetune"), "bake_wall_s": round(bake_s, 1), "mb": round(scene_mb(out), 2), "baked": str(out)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lego", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--lego-run", type=Path, default=Path("runs/multiscale/ngp_10min_200px"))
    ap.add_argument("--maryrose", type=Path, default=MARYROSE)
    ap.add_argument("--out", type=Path, default=Path("runs/bake"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    result = {"what": "nerfkit eval of a field and of its bake (nerfkit bake, default settings)", "provenance": provenance()}
    if not (a.lego_run / "config.json").is_file():
        nerfkit("train", str(a.lego), "--out", str(a.lego_run), "--preset", "ngp", *SEED, "--max-minutes", "10",
                "--no-progress", "--overwrite")
    result["lego"] = bake_and_score(a.lego_run, a.out / "lego", "val[50:100]", "val_50_100")
    nerfkit("bake", str(a.lego_run), "--out", str(a.out / "lego_no_finetune"), "--finetune-minutes", "0", "--overwrite",
            "--no-progress")
    nerfkit("eval", str(a.lego_run), "--split", "val[50:100]", "--every", "5", "--baked", str(a.out / "lego_no_finetune"),
            "--overwrite")
    ev = json.loads((a.lego_run / "eval_val_50_100_baked.json").read_text())
    result["lego_no_finetune"] = {"baked_psnr": ev["psnr"], "baked_ssim": ev["ssim"], "n_views": ev["n_views"], "every": 5}
    mary_run = a.out / "maryrose_ngp_6min"
    nerfkit("train", str(a.maryrose), "--out", str(mary_run), "--preset", "ngp", "--max-minutes", "6", "--downscale", "2",
            "--no-progress", "--overwrite")
    result["maryrose"] = bake_and_score(mary_run, a.out / "maryrose", "test", "test")
    path = a.results / "bake_quality.json"
    path.write_text(json.dumps(result, indent=2))
    for k in ("lego", "maryrose"):
        r = result[k]
        print(f"{k}: field {r['field_psnr']:.2f} dB / {r['field_ssim']:.3f}, baked {r['baked_psnr']:.2f} / "
              f"{r['baked_ssim']:.3f}, {r['mb']} MB, {r['bricks']} bricks at {r['resolution']}^3, {r['bake_wall_s']} s")
    print(f"lego without fine-tuning: {result['lego_no_finetune']['baked_psnr']:.2f} dB (every 5th view); wrote {path}")


if __name__ == "__main__":
    main()
