"""A posed capture through the command line, preset against preset in one sitting: held-out PSNR against the
CLI's own wall clock, and the held-out photos side by side.

    python benchmarks/capture_cli.py [--data MARYROSE] [--presets ngp splat] [--minutes 10] [--downscale 2]
                                     [--name maryrose] [--out runs/capture_cli] [--common=--no-masks]
                                     [--fit-poses N] [--fit-colour]

For each preset P, one fresh run of exactly what a user types:

    nerfkit train DATA --out OUT/<P> --preset P --max-minutes M --downscale D [COMMON]
    nerfkit eval OUT/<P> --split test
    nerfkit eval OUT/<P> --split test --fit-poses N     (--fit-poses N, splat runs: under "fitted")
    nerfkit eval OUT/<P> --split test --fit-colour [--fit-poses N]   (--fit-colour: under "fitted_colour", each
        held-out photo's colour fitted on its left half and its right half scored, with its pose fitted first
        where --fit-poses N is given and the preset supports it)

A preset may be a variant LABEL=ARGS (e.g. "splat-random=--preset splat --init-points random"): the run is
OUT/LABEL, trained with ARGS in place of --preset LABEL. `--data-for LABEL=PATH` trains that variant on another
capture of the same photos and poses (e.g. with other points; benchmarks/splat_start.py).

(the wall clock and peak resident memory are the whole `nerfkit train` process's; the splat runs' Gaussians in
use at the end are from its metrics.jsonl; PSNR and SSIM are `nerfkit eval`'s over every held-out photo).
Writes benchmarks/results/<name>_cli.json (with the commit it ran on) and <name>_cli.jpg: three held-out
photos (first, middle, last), each as the runs see it and every preset's render.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "real" / "maryrose"


def nerfkit(*args: str) -> tuple[float, str]:
    """Run the CLI in its own process (as a user would); (wall seconds, stdout)."""
    wall, out, _ = nerfkit_peak(*args)
    return wall, out


def nerfkit_peak(*args: str) -> tuple[float, str, float]:
    """nerfkit(*args) and the process's peak resident memory in GiB (its own rusage, os.wait4)."""
    t0 = time.perf_counter()
    with subprocess.Popen([sys.executable, "-m", "nerfkit", *args], stdout=subprocess.PIPE, text=True) as p:
        out = p.stdout.read()
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise SystemExit(f"nerfkit {' '.join(args)} failed (exit {p.returncode})")
    return time.perf_counter() - t0, out, usage.ru_maxrss / 2**20  # ru_maxrss: KiB on Linux


def side_by_side(runs: dict[str, Path], views: list[int], out: Path) -> None:
    """Rows of held-out photos: the photo as the runs see it (masked, composited, shrunk), then each preset's
    render (eval's RUN/eval_test/view_NNN_rgb.png)."""
    import imageio.v3 as iio

    from nerfkit.core.viz import to_uint8
    from nerfkit.data.loader import load_scene
    from nerfkit.run.folder import RunFolder

    first = RunFolder(next(iter(runs.values())))
    d = first.config().data
    photos = load_scene(first.data_dir(), "test", format=d.format, downscale=d.downscale, target_width=d.target_width,
                        background=d.background, masks=d.masks, holdout_every=d.holdout_every,
                        undistort=d.undistort).images
    tiles = [[to_uint8(photos[k])] + [iio.imread(r / "eval_test" / f"view_{k:03d}_rgb.png")[..., :3]
                                      for r in runs.values()] for k in views]
    h, w = min(t.shape[0] for row in tiles for t in row), min(t.shape[1] for row in tiles for t in row)
    # (splats render the undistorted pinhole camera, which may be a pixel smaller than the photos: cropped alike)
    rows = [np.concatenate([t[:h, :w] for t in row], axis=1) for row in tiles]
    iio.imwrite(out, np.concatenate(rows, axis=0), quality=90)


def fitted_colour(run: Path, poses: int) -> dict:
    """`nerfkit eval RUN --split test --fit-colour` (with --fit-poses N where poses N > 0): the right halves' PSNR
    and SSIM after the colour map, and the same halves before it."""
    extra = ["--fit-poses", str(poses)] if poses else []
    wall, _ = nerfkit("eval", str(run), "--split", "test", "--fit-colour", *extra, "--overwrite")
    name = "eval_test_fitted_colour.json" if poses else "eval_test_colour.json"
    ev = json.loads((run / name).read_text())
    return {"fit_poses": poses, "psnr": round(ev["psnr"], 3), "ssim": round(ev["ssim"], 4),
            "psnr_unmapped": round(float(np.mean([v["colour_fit"]["psnr_unfitted"] for v in ev["per_view"]])), 3),
            "per_view_psnr": [round(v["psnr"], 3) for v in ev["per_view"]], "eval_wall_s": round(wall, 1)}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--presets", nargs="+", default=["ngp", "splat"])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--downscale", type=int, default=2)
    ap.add_argument("--name", default="maryrose")
    ap.add_argument("--out", type=Path, default=Path("runs/capture_cli"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    ap.add_argument("--common", default="", help="arguments added to every nerfkit train")
    ap.add_argument("--fit-poses", type=int, default=0,
                    help="N > 0: also `nerfkit eval --fit-poses N` for the presets that support it (splats): each "
                         "held-out photo scored after its pose is fitted to it against the frozen scene")
    ap.add_argument("--fit-colour", action="store_true",
                    help="also `nerfkit eval --fit-colour` (with --fit-poses N where the preset supports it): each "
                         "held-out photo's colour fitted on its left half and the right half scored")
    ap.add_argument("--data-for", action="append", default=[], metavar="LABEL=PATH",
                    help="train the variant LABEL on the capture PATH (same photos and poses) instead of --data")
    a = ap.parse_args(argv)
    from nerfkit.models.registry import method_class
    from nerfkit.run.folder import RunFolder

    data_for = dict(x.split("=", 1) for x in a.data_for)
    result = {"what": f"nerfkit train + nerfkit eval --split test on {a.data.name}, wall clock of the CLI",
              "data": str(a.data), "minutes": a.minutes, "downscale": a.downscale, "common": a.common, "presets": {},
              "provenance": provenance()}
    runs = {}
    for entry in a.presets:
        preset, _, args = entry.partition("=")
        run = a.out / preset
        data = data_for.get(preset, str(a.data))
        train_s, out, peak = nerfkit_peak("train", data, "--out", str(run),
                                          *(shlex.split(args) or ["--preset", preset]), "--max-minutes",
                                          f"{a.minutes:g}", "--downscale", str(a.downscale), "--no-progress",
                                          "--overwrite", *shlex.split(a.common))
        eval_s, _ = nerfkit("eval", str(run), "--split", "test", "--overwrite")
        ev = json.loads((run / "eval_test.json").read_text())
        m = re.search(r"step (\d+), ([\d.]+) steps/s", out)
        last = json.loads((run / "metrics.jsonl").read_text().splitlines()[-1])
        result["presets"][preset] = {"run": str(run), "data": data, "args": args or f"--preset {preset}",
                                     "train_wall_s": round(train_s, 1),
                                     "steps": int(m.group(1)) if m else None, "train_peak_gib": round(peak, 2),
                                     **({"gaussians": int(last["gaussians"])} if "gaussians" in last else {}),
                                     "psnr": round(ev["psnr"], 3),
                                     "ssim": round(ev["ssim"], 4), "views": ev["n_views"],
                                     "per_view_psnr": [round(v["psnr"], 3) for v in ev["per_view"]],
                                     "eval_wall_s": round(eval_s, 1)}
        runs[preset] = run
        print(f"{preset}: {result['presets'][preset]['steps']} steps in {train_s / 60:.2f} min, "
              f"{ev['psnr']:.2f} dB / SSIM {ev['ssim']:.4f} on {ev['n_views']} held-out photos", flush=True)
        fit_poses = a.fit_poses if method_class(RunFolder(run).config()).supports.fit_poses else 0
        if fit_poses:
            fit_s, _ = nerfkit("eval", str(run), "--split", "test", "--fit-poses", str(fit_poses), "--overwrite")
            fit = json.loads((run / "eval_test_fitted.json").read_text())
            result["presets"][preset]["fitted"] = {
                "fit_poses": a.fit_poses, "psnr": round(fit["psnr"], 3), "ssim": round(fit["ssim"], 4),
                "per_view_psnr": [round(v["psnr"], 3) for v in fit["per_view"]],
                "per_view_moved_degrees": [round(v["pose_fit"]["degrees"], 4) for v in fit["per_view"]],
                "eval_wall_s": round(fit_s, 1)}
            print(f"{preset}, poses fitted: {fit['psnr']:.2f} dB / SSIM {fit['ssim']:.4f}", flush=True)
        if a.fit_colour:
            result["presets"][preset]["fitted_colour"] = fitted_colour(run, fit_poses)
    a.results.mkdir(parents=True, exist_ok=True)
    path = a.results / f"{a.name}_cli.json"
    path.write_text(json.dumps(result, indent=2))
    n = next(iter(result["presets"].values()))["views"]
    side_by_side(runs, sorted({0, n // 2, n - 1}), path.with_suffix(".jpg"))
    print(f"wrote {path} and {path.with_suffix('.jpg')} (columns: ground truth, {', '.join(runs)})")


if __name__ == "__main__":
    main()
