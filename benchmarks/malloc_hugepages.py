"""What glibc's transparent huge pages for malloc's large blocks (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`, which
`nerfkit` gives itself: cli/hugepages.py) change for a user's training run: the same `nerfkit train` with and
without them, alternating (A B B A per preset), its wall clock, CPU time and minor page faults (getrusage of the
child).

    python benchmarks/malloc_hugepages.py [--data LEGO] [--presets ngp splat] [--steps 300] [--rounds 2]
                                          [--out runs/malloc_hugepages] [--name malloc_hugepages]

Each run is exactly what a user types on lego's seed protocol at 200x200, stopped after a number of steps:

    nerfkit train LEGO --preset P --train-split "train,val[0:50]" --val-split "val[50:100]" --target-width 200
                       --max-steps STEPS --no-progress --out OUT/P_<variant>_<k>

with $GLIBC_TUNABLES unset and $NERFKIT_HUGEPAGES=off (`off`), or as a user runs it, $GLIBC_TUNABLES unset
(`on`: the command line restarts itself with the tunable). The kernel must allow transparent huge pages
(/sys/kernel/mm/transparent_hugepage/enabled `always` or `madvise`), which the record keeps. Writes
benchmarks/results/<name>.json (with the commit).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

from provenance import provenance

from nerfkit.cli.hugepages import THP, TUNABLE

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "nerf_synthetic" / "lego"
SEED = ["--train-split", "train,val[0:50]", "--val-split", "val[50:100]", "--target-width", "200"]


def train(data: Path, preset: str, steps: int, out: Path, hugepages: bool) -> dict:
    """One `nerfkit train` in a child process: wall seconds, user and system CPU seconds, minor page faults."""
    env = {k: v for k, v in os.environ.items() if k not in ("GLIBC_TUNABLES", "NERFKIT_HUGEPAGES")}
    if not hugepages:
        env["NERFKIT_HUGEPAGES"] = "off"
    shutil.rmtree(out, ignore_errors=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "nerfkit", "train", str(data), "--preset", preset, *SEED,
                        "--max-steps", str(steps), "--no-progress", "--out", str(out)], env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"nerfkit train --preset {preset} failed:\n{r.stderr[-2000:]}")
    return {"wall_s": round(wall, 2), "user_s": round(after.ru_utime - before.ru_utime, 2),
            "system_s": round(after.ru_stime - before.ru_stime, 2), "minor_faults": after.ru_minflt - before.ru_minflt}


def summary(runs: list[dict]) -> dict:
    return {key: round(sum(r[key] for r in runs) / len(runs), 2) for key in runs[0]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--presets", nargs="+", default=["ngp", "splat"])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=2, help="A B B A pairs per preset")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "malloc_hugepages")
    ap.add_argument("--name", default="malloc_hugepages")
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args()
    if not (args.data / "transforms_train.json").exists():
        sys.exit(f"no lego capture at {args.data}: pass --data")
    record = {"provenance": provenance(), "steps": args.steps, "tunable": f"{TUNABLE}=1",
              "transparent_hugepage": THP.read_text().strip() if THP.exists() else None, "presets": {}}
    for preset in args.presets:
        runs = {"off": [], "on": []}
        order = [False, True, True, False] * args.rounds
        for k, on in enumerate(order):
            variant = "on" if on else "off"
            runs[variant].append(train(args.data, preset, args.steps, args.out / f"{preset}_{variant}_{k}", on))
            print(preset, variant, runs[variant][-1], flush=True)
        off, on = summary(runs["off"]), summary(runs["on"])
        record["presets"][preset] = {"off": off, "on": on, "runs": runs,
                                     "wall_ratio": round(on["wall_s"] / off["wall_s"], 3),
                                     "cpu_ratio": round((on["user_s"] + on["system_s"]) / (off["user_s"] + off["system_s"]), 3)}
        print(preset, "on/off wall", record["presets"][preset]["wall_ratio"], "cpu", record["presets"][preset]["cpu_ratio"])
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / f"{args.name}.json").write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
