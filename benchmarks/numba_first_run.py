"""A splat run's first start after installing: the CPU rasteriser's numba kernels compile once, then load from
numba's on-disk cache. Both runs are what a user types:

    python benchmarks/numba_first_run.py [--pairs 2] [--steps 100] [--size 128] [--out runs/numba_first_run]

On the procedural scene (SIZE px), `nerfkit train SCENE --preset splat --max-steps STEPS` is timed (the whole
process), alternately with an empty numba cache (a fresh $NUMBA_CACHE_DIR: every kernel compiles, as on the
first run after `pip install`) and with the cache the previous cold run filled (as on every later run). JAX's
own compilation cache is off in both ($NERFKIT_COMPILE_CACHE=off), so the pair differs only in numba's kernels.
Writes benchmarks/results/numba_first_run.json (with the commit): each run's wall clock and the mean difference.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

from clirun import nerfkit
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def train(scene: Path, out: Path, steps: int, numba_cache: str) -> float:
    """Wall seconds of one `nerfkit train --preset splat` process with the given numba cache folder."""
    env = {**os.environ, "NUMBA_CACHE_DIR": numba_cache, "NERFKIT_COMPILE_CACHE": "off"}
    return nerfkit("train", scene, "--out", out, "--preset", "splat", "--max-steps", steps, "--no-progress",
                   "--overwrite", env=env)[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "numba_first_run")
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    from nerfkit.data.procedural.scene import make_scene

    scene = a.out / "scene"
    if not (scene / "transforms_train.json").is_file():
        make_scene(scene, size=a.size)
    rows = []
    for k in range(a.pairs):
        with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
            cold = train(scene, a.out / "run", a.steps, cache)
            warm = train(scene, a.out / "run", a.steps, cache)
        rows.append({"cold_s": round(cold, 1), "warm_s": round(warm, 1)})
        print(f"pair {k + 1}: {cold:.1f} s with an empty numba cache, {warm:.1f} s with it filled", flush=True)
    diff = sum(r["cold_s"] - r["warm_s"] for r in rows) / len(rows)
    result = {"what": f"nerfkit train --preset splat --max-steps {a.steps} on the procedural scene ({a.size} px), "
                      "whole process, numba's kernel cache empty (cold) then filled (warm), JAX's cache off",
              "steps": a.steps, "size": a.size, "pairs": rows, "first_run_extra_s": round(diff, 1),
              "provenance": provenance()}
    a.results.mkdir(parents=True, exist_ok=True)
    (a.results / "numba_first_run.json").write_text(json.dumps(result, indent=1))
    print(f"the first run after installing takes {diff:.1f} s longer (mean of {len(rows)} pairs); "
          f"wrote {a.results / 'numba_first_run.json'}")


if __name__ == "__main__":
    main()
