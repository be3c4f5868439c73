"""Training time alone on lego: train for a budget of training time, record val PSNR against it.

NOT the wall clock a user sees: this clock stops during its own validations, data loading and start-up
(for the CLI's wall clock, validation included, use benchmarks/lego_cli.py, which the README quotes).

    python benchmarks/lego_speed.py [--preset ngp] [--minutes 10] [--every-s 30] [--val-views 10]

Seed protocol at 200x200 (train + val[0:50], validate on val[50:100]). The clock counts
training only, compilation included; it is paused while the benchmark measures PSNR on
`--val-views` evenly spaced views of val[50:100] every `--every-s` seconds. At the end it
evaluates all 50 views, times one 800x800 render, prints time-to-26 dB, PSNR at 2, 5 and
10 minutes, steps/s and samples per ray, and writes a JSON and a PNG plot.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from provenance import provenance

from nerfkit.core.config import validate
from nerfkit.core.metrics import psnr
from nerfkit.core.presets import preset
from nerfkit.core.viz import plot_curves
from nerfkit.data.loader import load_frames, read_capture
from nerfkit.models.registry import build_model
from nerfkit.render.chunked import Renderer
from nerfkit.training.resolve import resolve_config
from nerfkit.training.step import init_state, make_optimizer, make_train_step
from nerfkit.training.validation import evenly_spaced

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "nerf_synthetic" / "lego"


def mean_psnr(renderer, state, data, ids) -> float:
    scores = []
    for k in ids:
        r = renderer.render_camera(state["params"], state["aux"], data.poses[k], data.cameras[k])
        scores.append(psnr(r["rgb"], data.images[k]))
    return float(np.mean(scores))


def psnr_at(records, seconds):
    """Val PSNR at `seconds` of training, linearly interpolated between measurements
    (None before the first measurement or after the last)."""
    ts = [r["elapsed"] for r in records]
    if not records or seconds < ts[0] or seconds > ts[-1] + 1e-6:
        return None
    return float(np.interp(seconds, ts, [r["psnr"] for r in records]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--preset", default="ngp")
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--every-s", type=float, default=30.0)
    ap.add_argument("--val-views", type=int, default=10, help="views of val[50:100] for the periodic curve")
    ap.add_argument("--target", type=float, default=26.0)
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    a = ap.parse_args()

    cfg = validate(preset(a.preset))
    d = cfg.data
    d.train_split, d.val_split, d.target_width = "train,val[0:50]", "val[50:100]", 200  # the seed protocol
    cap = read_capture(a.data, f"{d.train_split},{d.val_split}")
    train = load_frames(cap, d.train_split, target_width=d.target_width)
    val = load_frames(cap, d.val_split, target_width=d.target_width)
    cfg = resolve_config(cfg, cap, train)
    model = build_model(cfg)
    opt, _ = make_optimizer(cfg)
    state = init_state(model, opt, cfg.train.seed)
    step_fn = make_train_step(model, opt, train, cfg)
    renderer = Renderer(model, cfg.train.chunk)
    images, poses = jnp.asarray(train.images), jnp.asarray(train.poses)
    curve_ids = evenly_spaced(len(val), a.val_views)
    print(f"{a.preset}: {len(train)} train views, {len(val)} val views at {train.width}x{train.height}; "
          f"jax {jax.__version__} on {jax.devices()[0].platform}")

    records, spr = [], []
    budget = 60 * a.minutes
    trained, step, next_eval = 0.0, 0, a.every_s
    while trained < budget:
        t0 = time.perf_counter()
        state, m = step_fn(state, jnp.int32(step), images, poses)
        jax.block_until_ready(m)
        trained += time.perf_counter() - t0
        step += 1
        if "samples_per_ray" in m:
            spr.append(float(m["samples_per_ray"]))
        if trained >= next_eval or trained >= budget:
            p = mean_psnr(renderer, state, val, curve_ids)
            records.append({"elapsed": round(trained, 2), "step": step, "psnr": round(p, 3)})
            print(f"  {trained:7.1f} s  step {step:6d}  val PSNR {p:6.2f} dB ({len(curve_ids)} views)", flush=True)
            next_eval += a.every_s

    final = mean_psnr(renderer, state, val, range(len(val)))
    big = Renderer(model, cfg.train.chunk)
    focal800 = train.focal * 800 / train.width
    big.render_image(state["params"], state["aux"], val.poses[0], 800, 800, focal800)  # compile
    t0 = time.perf_counter()
    big.render_image(state["params"], state["aux"], val.poses[0], 800, 800, focal800)
    render_s = time.perf_counter() - t0

    # First crossing of the target, interpolated between the two measurements around it.
    hit, prev = None, None
    for r in records:
        if r["psnr"] >= a.target:
            hit = r["elapsed"] if prev is None else float(np.interp(
                a.target, [prev["psnr"], r["psnr"]], [prev["elapsed"], r["elapsed"]]))
            break
        prev = r
    result = {
        "clock": "training time alone: stopped during this script's validations, data loading and start-up "
                 "(not the CLI's wall clock; benchmarks/lego_cli.py measures that)",
        "preset": a.preset, "minutes": a.minutes, "steps": step, "steps_per_s": step / trained,
        "samples_per_ray_mean_last_100": float(np.mean(spr[-100:])) if spr else cfg.sampler.n_samples,
        f"time_to_{a.target:g}dB_s": hit,
        "psnr_at_2min": psnr_at(records, 120), "psnr_at_5min": psnr_at(records, 300),
        "psnr_at_10min": psnr_at(records, 600), "final_val_psnr_50_views": final,
        "render_800x800_s": render_s, "curve_views": curve_ids, "records": records, "provenance": provenance(),
    }
    a.out.mkdir(parents=True, exist_ok=True)
    stem = a.out / f"lego_speed_{a.preset}"
    stem.with_suffix(".json").write_text(json.dumps(result, indent=2))
    plot_curves({a.preset: ([r["elapsed"] / 60 for r in records], [r["psnr"] for r in records])},
                stem.with_suffix(".png"), "training time (min, compile included)", "val PSNR (dB)",
                f"lego 200x200, seed protocol: {a.preset}")
    fmt = lambda v: "n/a" if v is None else f"{v:.2f}"  # noqa: E731
    print("\n(training time alone: this clock stops during validation, data loading and start-up; "
          "benchmarks/lego_cli.py measures the CLI's wall clock)")
    print(f"steps: {step}  steps/s: {result['steps_per_s']:.2f}  samples/ray: {result['samples_per_ray_mean_last_100']:.1f}")
    print(f"time to {a.target:g} dB: {'not reached' if hit is None else f'{hit:.0f} s'}")
    print(f"PSNR at 2 / 5 / 10 min: {fmt(result['psnr_at_2min'])} / {fmt(result['psnr_at_5min'])} / "
          f"{fmt(result['psnr_at_10min'])} dB ({len(curve_ids)} views)")
    print(f"final val PSNR (all {len(val)} views of {d.val_split}): {final:.2f} dB")
    print(f"one 800x800 render: {render_s:.2f} s")
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.png')}")
    if not math.isfinite(final):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
