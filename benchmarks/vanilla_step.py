"""Train-step time of the vanilla NeRF presets (after compilation, median of several steps).

    python benchmarks/vanilla_step.py [--presets seed nerf] [--steps 10] [--size 200]

Uses the same jitted step as `nerfkit train` on synthetic images of the preset's size
(timing does not depend on image content), so numbers compare directly with other
implementations at identical settings (rays/step, samples/ray, D, W).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.presets import preset
from nerfkit.data.capture import SceneData
from nerfkit.models.registry import build_model
from nerfkit.rays.cameras import Camera, look_at
from nerfkit.training.step import init_state, make_optimizer, make_train_step


def fake_scene(n: int, size: int) -> SceneData:
    rng = np.random.default_rng(0)
    images = rng.random((n, size, size, 3), dtype=np.float32)
    poses = []
    for k in range(n):
        az, el = 2 * np.pi * k / n, 0.5
        eye = 4.0 * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        poses.append(look_at(eye, np.zeros(3)))
    focal = 0.5 * size / np.tan(0.5 * 0.6911112070083618)
    return SceneData(images, np.stack(poses), [Camera.pinhole(size, size, float(focal))] * n)


def time_preset(name: str, steps: int, size: int) -> dict:
    cfg = preset(name)
    data = fake_scene(20, size)
    model = build_model(cfg)
    opt, _ = make_optimizer(cfg)
    state = init_state(model, opt, 0)
    step_fn = make_train_step(model, opt, data, cfg)
    images, poses = jnp.asarray(data.images), jnp.asarray(data.poses)
    t0 = time.perf_counter()
    state, m = step_fn(state, jnp.int32(0), images, poses)
    jax.block_until_ready(m)
    compile_s = time.perf_counter() - t0
    times = []
    for s in range(1, steps + 1):
        t0 = time.perf_counter()
        state, m = step_fn(state, jnp.int32(s), images, poses)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
    s = cfg.sampler
    med = statistics.median(times)
    return {
        "preset": name, "D": cfg.field.depth, "W": cfg.field.width, "rays": cfg.train.batch_rays,
        "samples": s.n_samples + s.n_importance, "compile_s": round(compile_s, 2),
        "step_ms_median": round(1000 * med, 1), "step_ms_min": round(1000 * min(times), 1),
        "steps_per_s": round(1 / med, 2),
        "points_per_s": round((s.n_samples + (s.n_samples + s.n_importance if s.n_importance else 0))
                              * cfg.train.batch_rays / med),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="+", default=["seed", "nerf"])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--json", type=str, default=None, help="also write the results here")
    a = ap.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform} ({jax.device_count()} device)")
    rows = [time_preset(p, a.steps, a.size) for p in a.presets]
    hdr = f"{'preset':<6} {'D':>2} {'W':>4} {'rays':>5} {'samples':>7} {'compile s':>9} {'step ms':>8} {'steps/s':>7} {'pts/s':>10}"
    print(hdr)
    for r in rows:
        print(f"{r['preset']:<6} {r['D']:>2} {r['W']:>4} {r['rays']:>5} {r['samples']:>7} {r['compile_s']:>9} "
              f"{r['step_ms_median']:>8} {r['steps_per_s']:>7} {r['points_per_s']:>10}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()
