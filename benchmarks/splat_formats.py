"""Each splat file format on a trained scene, through the command line: size, and its render against the .ply's.

    python benchmarks/splat_formats.py --scene lego|maryrose [--minutes 2] [--finetune-minutes 0]
                                       [--out runs/splat_formats]

1. One splat run, as a user trains it (lego: the seed protocol at 200 px; maryrose: masks, --downscale 2):
       nerfkit train DATA --out OUT/run --preset splat --max-minutes M ...
2. For each format F (.ply, .spz, .splat, .glb, .sog):
       nerfkit export splat OUT/run --out OUT/scene.F
       nerfkit import splat OUT/scene.F --data DATA --out OUT/import_F
       nerfkit eval OUT/import_F --split HELD_OUT --downscale D
   The file's bytes, its PSNR / SSIM against the held-out photos, and the PSNR of its renders against the .ply's
   renders of the same views (eval's 8-bit PNGs: null where they are identical; 8-bit rounding alone ~59 dB).
3. With --finetune-minutes T: the .ply cut to SH degree 0 (a degraded scene, as a file from a tool without view
   dependence), imported and scored, then `nerfkit train DATA --init scene_sh0.ply --max-minutes T` from it,
   scored again: what fine-tuning a foreign file on its capture recovers.

Writes benchmarks/results/splat_formats_<scene>.json (with the commit it ran on).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from clirun import nerfkit
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
SCENES = {  # data, training arguments, held-out split, eval arguments
    "lego": (SHARED / "nerf_synthetic" / "lego",
             ["--train-split", "train,val[0:50]", "--val-split", "val[50:100]", "--target-width", "200"],
             "val[50:100]", ["--downscale", "2"]),
    "maryrose": (SHARED / "real" / "maryrose", ["--downscale", "2"], "test", ["--downscale", "2"]),
}
FORMATS = ("ply", "spz", "splat", "glb", "sog")


def renders(run: Path, split: str) -> list[np.ndarray]:
    """eval's renders of the split (RUN/eval_<split>/view_NNN_rgb.png), float in [0, 1]."""
    import imageio.v3 as iio

    folder = next(p for p in run.iterdir() if p.is_dir() and p.name.startswith("eval_"))
    return [iio.imread(p)[..., :3].astype(np.float64) / 255 for p in sorted(folder.glob("view_*_rgb.png"))]


def mean_psnr(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    mse = [float(np.mean((x - y) ** 2)) for x, y in zip(a, b)]
    return float(np.mean([10 * np.log10(1 / m) if m > 0 else np.inf for m in mse]))


def scored(run: Path, split: str, eval_args: list[str]) -> dict:
    """nerfkit eval RUN --split SPLIT: {psnr, ssim, seconds}."""
    secs, _ = nerfkit("eval", run, "--split", split, "--overwrite", *eval_args)
    ev = json.loads(next(run.glob("eval_*.json")).read_text())
    return {"psnr": round(ev["psnr"], 3), "ssim": round(ev["ssim"], 4), "seconds": round(secs, 1)}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=sorted(SCENES), required=True)
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--finetune-minutes", type=float, default=0.0)
    ap.add_argument("--out", type=Path, default=Path("runs/splat_formats"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args(argv)
    data, train_args, split, eval_args = SCENES[a.scene]
    out = a.out / a.scene
    run = out / "run"
    secs, _ = nerfkit("train", data, "--out", run, "--preset", "splat", "--max-minutes", a.minutes, "--no-progress",
                      "--overwrite", *train_args)
    record = {"scene": a.scene, "train": {"minutes": a.minutes, "wall_seconds": round(secs, 1),
                                          "args": train_args, "run": scored(run, split, eval_args)},
              "held_out": split, "formats": {}}
    shown = {}
    for fmt in FORMATS:
        file = out / f"scene.{fmt}"
        secs, _ = nerfkit("export", "splat", run, "--out", file, "--overwrite")
        rec = json.loads((run / "exports" / "export_splat.json").read_text())
        imported = out / f"import_{fmt}"
        nerfkit("import", "splat", file, "--data", data, "--out", imported, "--overwrite")
        record["formats"][fmt] = {"format": rec["format"], "bytes": rec["bytes"], "gaussians": rec["gaussians"],
                                  "sh_degree": rec["sh_degree"], "export_seconds": round(secs, 1),
                                  **scored(imported, split, eval_args)}
        shown[fmt] = renders(imported, split)
        print(fmt, record["formats"][fmt], flush=True)
    ply = record["formats"]["ply"]
    for fmt in FORMATS:
        f = record["formats"][fmt]
        f["smaller_than_ply"] = round(ply["bytes"] / f["bytes"], 2)
        same = mean_psnr(shown["ply"], shown[fmt])
        f["psnr_vs_ply_render"] = round(same, 2) if np.isfinite(same) else None  # None: identical renders
        f["psnr_loss_vs_ply"] = round(ply["psnr"] - f["psnr"], 3)
    if a.finetune_minutes:
        record["finetune"] = finetune(out, data, train_args, split, eval_args, a.finetune_minutes)
    record["provenance"] = provenance()
    path = a.results / f"splat_formats_{a.scene}.json"
    path.write_text(json.dumps(record, indent=2))
    print(json.dumps(record, indent=2))
    print(f"wrote {path}")


def finetune(out: Path, data: Path, train_args: list[str], split: str, eval_args: list[str], minutes: float) -> dict:
    """The .ply cut to SH degree 0, imported and scored; then trained from (--init) for `minutes` and scored."""
    from nerfkit.models.splat.formats import read_gaussians
    from nerfkit.models.splat.formats.ply import export_ply

    g, _, _ = read_gaussians(out / "scene.ply")
    sh0 = out / "scene_sh0.ply"
    export_ply(sh0, g, sh_degree=0)
    nerfkit("import", "splat", sh0, "--data", data, "--out", out / "import_sh0", "--overwrite")
    before = scored(out / "import_sh0", split, eval_args)
    run = out / "finetuned"
    secs, _ = nerfkit("train", data, "--out", run, "--preset", "splat", "--init", sh0, "--capacity",
                      str(max(50_000, len(g["means"]))), "--max-minutes", minutes, "--no-progress", "--overwrite",
                      *train_args)
    return {"degraded": "the .ply's Gaussians with SH degree 0", "gaussians": int(len(g["means"])),
            "imported": before, "minutes": minutes, "wall_seconds": round(secs, 1),
            "after": scored(run, split, eval_args)}


if __name__ == "__main__":
    main()
