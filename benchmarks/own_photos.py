"""The README's "Your own photos" path at full size, as a user runs it, with each preset: what it costs and what
it gives.

    python benchmarks/own_photos.py --photos ../shared/data/real/buddha/images --name buddha
    python benchmarks/own_photos.py --photos ../shared/data/real/maryrose/images \\
        --masks ../shared/data/real/maryrose/masks --name maryrose
    python benchmarks/own_photos.py --video runs/video/room.mp4 --name procedural_video --presets splat

runs, each in its own process, exactly what the README says (no size or budget flags: the presets' defaults):

    nerfkit process-data images PHOTOS --out OUT/data [--masks MASKS]   (or: process-data video VIDEO --out OUT/data)
    nerfkit train OUT/data --out OUT/<P> --preset P                    (P in --presets)
    nerfkit eval OUT/<P> --split test --overwrite                      (the run's own resolution)
    nerfkit eval OUT/<P> --split test --downscale 4 --overwrite        (a quarter of the photos' size)
    nerfkit render OUT/<P> --orbit 60

and writes benchmarks/results/own_photos_<name>.json (with the commit it ran on): the SfM's registration, time
and printed lines; per preset the training wall clock, steps, rays per step and samples per ray (the fields),
the share of the run spent validating, the held-out PSNR / SSIM, seconds per evaluated view at both sizes and
per orbit frame; and own_photos_<name>.jpg (eval's picture of the first held-out photo, a row per preset).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
from pathlib import Path

import numpy as np
from clirun import nerfkit
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def rows(path: Path) -> list[dict]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()] if path.is_file() else []


def one_preset(data: Path, run: Path, preset: str) -> dict:
    """train, eval (twice), render --orbit 60 of one preset; the figures the module docstring lists."""
    run.mkdir(parents=True, exist_ok=True)
    train_s, out = nerfkit("train", str(data), "--out", str(run), "--preset", preset, "--overwrite",
                           stderr=run.parent / f"{preset}_train_progress.txt")  # with progress: the log lines
    metrics, vals = rows(run / "metrics.jsonl"), rows(run / "val_metrics.jsonl")
    m = re.search(r"step (\d+), ([\d.]+) steps/s", out)
    res = {"train_wall_s": round(train_s, 1), "steps": int(m.group(1)) if m else None,
           "log": [line for line in out.splitlines() if line.split(":")[0] in
                   ("data", "lens", "scene", "slow", "appearance embeddings", "model", "validation", "budget",
                    "splat init")],
           "validations": [{k: v[k] for k in ("step", "psnr", "seconds")} for v in vals],
           "validation_share": round(sum(v["seconds"] for v in vals) / train_s, 4)}
    if metrics and "rays" in metrics[0]:
        res["rays_per_step"] = round(float(np.mean([r["rays"] for r in metrics])), 1)
        res["samples_per_ray"] = round(float(np.mean([r["samples_per_ray"] for r in metrics])), 1)
    for label, extra in (("eval", []), ("eval_downscale4", ["--downscale", "4"])):
        eval_s, _ = nerfkit("eval", str(run), "--split", "test", "--overwrite", *extra)
        ev = json.loads((run / "eval_test.json").read_text())
        res[label] = {"psnr": round(ev["psnr"], 3), "ssim": round(ev["ssim"], 4), "views": ev["n_views"],
                      "width": ev["width"], "height": ev["height"], "wall_s": round(eval_s, 1),
                      "seconds_per_view": round(ev["seconds_per_view"], 2)}
        if not extra:
            shutil.copytree(run / "eval_test", run / "eval_test_full", dirs_exist_ok=True)
    render_s, _ = nerfkit("render", str(run), "--orbit", "60", "--overwrite")
    res["orbit60_wall_s"] = round(render_s, 1)
    info = json.loads(next((run / "renders").glob("orbit60_*/render.json")).read_text())
    res["orbit60"] = {k: info[k] for k in ("frames", "width", "height", "seconds_per_frame")}
    return res


def picture(runs: dict[str, Path], out: Path) -> None:
    """Eval's picture of the first held-out photo (ground truth | render | depth), one row per preset."""
    import imageio.v3 as iio

    rows_ = [iio.imread(r / "eval_test_full" / "view_000.png")[..., :3] for r in runs.values()]
    w = min(x.shape[1] for x in rows_)
    iio.imwrite(out, np.concatenate([x[:, :w] for x in rows_], axis=0), quality=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    source = ap.add_mutually_exclusive_group(required=True)
    source.add_argument("--photos", type=Path)
    source.add_argument("--video", type=Path, help="a video instead of photos (process-data video)")
    ap.add_argument("--masks", type=Path)
    ap.add_argument("--name", required=True)
    ap.add_argument("--presets", nargs="+", default=["ngp", "splat"])
    ap.add_argument("--out", type=Path, default=Path("runs/own_photos"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    out = a.out / a.name
    data = out / "data"
    result = {"what": "the README's own-photos path at full size (process-data, train, eval, render --orbit 60), "
                      "the presets' defaults, wall clock of the CLI", "photos": str(a.photos) if a.photos else None,
              "video": str(a.video) if a.video else None,
              "masks": str(a.masks) if a.masks else None, "provenance": provenance(), "presets": {}}
    kind, source = ("video", a.video) if a.video else ("images", a.photos)
    args = ["process-data", kind, str(source), "--out", str(data), "--overwrite", "--no-progress"]
    sfm_s, printed = nerfkit(*args, *(["--masks", str(a.masks)] if a.masks else []))
    info = json.loads((data / "process.json").read_text())
    result["process_data"] = {"wall_s": round(sfm_s, 1), "photos": info["photos"], "registered": info["registered"],
                              "points": info["points"], "camera": info["camera"],
                              "log": [line for line in printed.splitlines() if line.strip()]}
    print(f"process-data: {info['registered']} of {info['photos']} photos in {sfm_s / 60:.1f} min", flush=True)
    runs = {}
    for preset in a.presets:
        runs[preset] = out / preset
        r = result["presets"][preset] = one_preset(data, runs[preset], preset)
        rays = f", {r['rays_per_step']:.0f} rays per step" if "rays_per_step" in r else ""
        full, small = r["eval"], r["eval_downscale4"]
        print(f"{preset}: {r['steps']} steps in {r['train_wall_s'] / 60:.2f} min{rays}, validation "
              f"{100 * r['validation_share']:.1f}% of it; held-out {full['psnr']:.2f} dB / SSIM {full['ssim']:.4f}; "
              f"eval {full['seconds_per_view']:.1f} s per {full['width']}x{full['height']} view, "
              f"{small['seconds_per_view']:.1f} s at --downscale 4; orbit {r['orbit60_wall_s'] / 60:.1f} min for 60 "
              f"frames", flush=True)
    a.results.mkdir(parents=True, exist_ok=True)
    path = a.results / f"own_photos_{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    picture(runs, path.with_suffix(".jpg"))
    print(f"wrote {path} and {path.with_suffix('.jpg')} (rows: {', '.join(a.presets)})")


if __name__ == "__main__":
    main()
