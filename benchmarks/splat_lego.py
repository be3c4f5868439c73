"""3D Gaussian Splatting on lego on this CPU: PSNR against training time, and the 800x800 render time.

    python benchmarks/splat_lego.py [--minutes 10] [--strategy mcmc] [--capacity 50000] [--every-s 30]
                                    [--set key=value ...] [--name splat_lego] [--ply out.ply]

Seed protocol (the same as benchmarks/lego_speed.py for the NeRF presets): train on
train + val[0:50] at 200x200 (white background), evaluate on val[50:100] at 200x200.
The clock counts training only, compilation included; it stops while this script measures:

  - every --every-s seconds: PSNR on 10 evenly spaced views of val[50:100] (the curve; the
    same views as lego_speed.py's curve),
  - at 2, 5 and 10 minutes (those within --minutes): PSNR and SSIM on all 50 views,
  - at the end: all 50 views, Gaussian count, and the time of one 800x800 render (the first
    val camera scaled to 800 px; min of 3 after a compiling run).

Writes benchmarks/results/{name}.json (with provenance) and {name}.png (this curve and, when
benchmarks/results/lego_speed_ngp.json exists, the hash-grid NeRF's for comparison).
--set overrides SplatConfig fields (ints, floats, or classic.<field> for the classic schedule).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
from provenance import provenance

from nerfkit.data.loader import load_frames, read_capture
from nerfkit.models.splat.densify import ClassicSchedule
from nerfkit.models.splat.strategy import STRATEGIES, Window
from nerfkit.models.splat.gaussians import render
from nerfkit.models.splat.gaussians import evaluate
from nerfkit.models.splat.fit import train_splats
from nerfkit.models.splat.train import SplatConfig

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "nerf_synthetic" / "lego"
CHECKPOINTS_S = (120.0, 300.0, 600.0)


def evenly_spaced(n: int, k: int) -> list[int]:
    """k evenly spaced indices of range(n) (lego_speed.py's curve views)."""
    return sorted({int(round(x)) for x in np.linspace(0, n - 1, min(k, n))})


def parse_sets(items: list[str]) -> dict:
    """{"field": value} from ["field=value", ...]; classic.<f>=v go into the Classic strategy's ClassicSchedule,
    window.<f>=v into the strategy's Window (strategy.py)."""
    out, classic, window = {}, {}, {}
    for item in items:
        key, value = item.split("=", 1)
        try:
            value = json.loads(value)
        except json.JSONDecodeError:
            pass
        if key.startswith("classic."):
            classic[key.split(".", 1)[1]] = value
        elif key.startswith("window."):
            window[key.split(".", 1)[1]] = value
        else:
            out[key] = value
    if classic or window:
        out["strategy_settings"] = {"schedule": ClassicSchedule(**classic)} if classic else {}
        if window:
            out["strategy_settings"]["window"] = Window(**window)
    return out


def time_render(params, pose, camera, reps: int = 3) -> float:
    """Min seconds of one render (rgb + depth) after a compiling run."""
    render(params, pose, camera)
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        render(params, pose, camera)
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--every-s", type=float, default=30.0)
    ap.add_argument("--strategy", default=None, help="mcmc, classic or none (default: SplatConfig's)")
    ap.add_argument("--capacity", type=int, default=None)
    ap.add_argument("--set", nargs="*", default=[], help="SplatConfig overrides, field=value")
    ap.add_argument("--name", default="splat_lego")
    ap.add_argument("--ply", type=Path, default=None, help="also export the final Gaussians here")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    overrides = parse_sets(a.set)
    settings = overrides.pop("strategy_settings", {})
    if a.strategy or settings:
        overrides["strategy"] = STRATEGIES[a.strategy or SplatConfig().strategy.name](**settings)
    if a.capacity:
        overrides["capacity"] = a.capacity
    cfg = SplatConfig(**overrides)
    cap = read_capture(a.data, "train,val[0:50],val[50:100]")
    train = load_frames(cap, "train,val[0:50]", target_width=200)
    val = load_frames(cap, "val[50:100]", target_width=200)
    curve_ids = evenly_spaced(len(val), 10)
    print(f"splat {cfg.strategy}: {len(train)} train views, {len(val)} val views at {train.width}x{train.height}, "
          f"capacity {cfg.capacity}")

    records, checkpoints = [], {}
    pending = [c for c in CHECKPOINTS_S if c <= 60 * a.minutes + 1e-6]

    def score(params, ids):
        return evaluate(params, val.images[ids], val.poses[ids], [val.cameras[i] for i in ids])

    def on_tick(step, elapsed, params, active):
        p = {k: np.asarray(v)[active] for k, v in params.items()}
        curve = score(p, curve_ids)
        records.append({"elapsed": round(elapsed, 2), "step": step, "psnr": round(curve["psnr_mean"], 3),
                        "gaussians": int(active.sum())})
        line = f"  {elapsed:7.1f} s  step {step:6d}  {int(active.sum()):6d} Gaussians  PSNR {curve['psnr_mean']:6.2f} dB"
        while pending and elapsed >= pending[0] - 1.0:
            full = score(p, list(range(len(val))))
            checkpoints[f"{pending[0] / 60:g}min"] = {
                "elapsed": round(elapsed, 2), "step": step, "gaussians": int(active.sum()),
                "psnr": round(full["psnr_mean"], 3), "ssim": round(full["ssim_mean"], 4)}
            line += f"  | {pending.pop(0) / 60:g} min, all {len(val)} views: {full['psnr_mean']:.2f} dB"
        print(line, flush=True)

    params, log = train_splats(train.images, train.poses, train.cameras, (1.0, 1.0, 1.0), cfg, minutes=a.minutes,
                               callback=on_tick, callback_every_s=a.every_s)
    final = score(params, list(range(len(val))))
    cam800 = val.cameras[0].with_size(800, 800)
    render_s = time_render(params, val.poses[0], cam800)
    steps, trained = log[-1][0], log[-1][1]
    result = {
        "clock": "training time alone (compilation included), stopped during this script's evaluations",
        "method": "3DGS", "strategy": cfg.strategy, "minutes": a.minutes,
        "config": json.loads(json.dumps({**dataclasses.asdict(cfg), "strategy": {
            "name": cfg.strategy.name, **dataclasses.asdict(cfg.strategy)}})),
        "steps": steps, "steps_per_s": steps / trained, "gaussians": len(params["means"]),
        **{f"psnr_at_{k}": v["psnr"] for k, v in checkpoints.items()},
        "checkpoints_50_views": checkpoints,
        "final_val_psnr_50_views": final["psnr_mean"], "final_val_ssim_50_views": final["ssim_mean"],
        "render_800x800_s": render_s, "curve_views": curve_ids, "records": records,
        "loss_log": [{"step": s, "elapsed": round(t, 2), "loss": round(l, 5)} for s, t, l in log[:: max(1, len(log) // 200)]],
        "provenance": provenance(),
    }
    a.out.mkdir(parents=True, exist_ok=True)
    stem = a.out / a.name
    stem.with_suffix(".json").write_text(json.dumps(result, indent=2))
    plot(records, stem.with_suffix(".png"), cfg)
    if a.ply:
        from nerfkit.models.splat.formats.ply import export_ply

        export_ply(a.ply, params)
    print(f"\nsteps {steps} ({result['steps_per_s']:.2f}/s), {result['gaussians']} Gaussians")
    for k, v in checkpoints.items():
        print(f"{k}: {v['psnr']:.2f} dB, SSIM {v['ssim']:.4f} (all {len(val)} views, step {v['step']})")
    print(f"final: {final['psnr_mean']:.2f} dB, SSIM {final['ssim_mean']:.4f}; one 800x800 render {render_s:.3f} s")
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.png')}")


def plot(records, path: Path, cfg: SplatConfig) -> None:
    from nerfkit.core.viz import plot_curves

    series = {f"3DGS {cfg.strategy} ({cfg.capacity // 1000}k)": ([r["elapsed"] / 60 for r in records],
                                                                   [r["psnr"] for r in records])}
    ngp = ROOT / "benchmarks" / "results" / "lego_speed_ngp.json"
    if ngp.exists():
        rec = json.loads(ngp.read_text())["records"]
        series["hash-grid NeRF (ngp)"] = ([r["elapsed"] / 60 for r in rec], [r["psnr"] for r in rec])
    plot_curves(series, path, "training time (min, compile included)", "val PSNR (dB, 10 views)",
                "lego 200x200, seed protocol")


if __name__ == "__main__":
    main()
