"""What pose refinement costs a ray preset's training step: `nerfkit train` on the procedural unbounded capture
(no masks) with --pose-refine off and on, in alternating order, steps per second from the run's own log.

    python benchmarks/pose_refine_speed.py [--preset ngp] [--steps 250] [--size 64] [--repeats 1]

Speed is (s2 - s1) / (elapsed(s2) - elapsed(s1)) between the first logged step at or after --skip (compilation
and the first steps left out) and the last step. Writes benchmarks/results/<name>.json with its provenance.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def steps_per_second(run: Path, skip: int) -> float:
    rows = [json.loads(x) for x in (run / "metrics.jsonl").read_text().splitlines()]
    first = next(r for r in rows if r["step"] >= skip)
    last = rows[-1]
    return (last["step"] - first["step"]) / (last["elapsed"] - first["elapsed"])


def main() -> None:
    from nerfkit.cli.main import main as nerfkit
    from nerfkit.data.procedural.captures import make_capture

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="ngp")
    ap.add_argument("--steps", type=int, default=250)
    ap.add_argument("--skip", type=int, default=50)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--views", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=1, help="pairs of runs (off, on), each pair's order alternating")
    ap.add_argument("--out", type=Path, default=Path("runs/pose_refine_speed"))
    ap.add_argument("--name", default=None, help="result name (default pose_refine_speed_<preset>)")
    a = ap.parse_args()
    cap = make_capture(a.out / "cap", "nerfstudio", n_views=a.views, size=a.size, seed=3, environment=True)
    result = {"what": __doc__.split("\n\n")[0], "preset": a.preset, "steps": a.steps, "skip": a.skip, "size": a.size,
              "views": a.views, "runs": [], "provenance": provenance()}
    for k in range(a.repeats):
        for refine in (("off", "on") if k % 2 == 0 else ("on", "off")):
            run = a.out / f"{refine}_{k}"
            argv = ["train", str(cap), "--out", str(run), "--preset", a.preset, "--max-steps", str(a.steps),
                    "--val-every", str(a.steps), "--ckpt-every", str(a.steps), "--no-progress", "--overwrite",
                    "--pose-refine", refine]
            if nerfkit(argv) != 0:
                raise SystemExit(f"nerfkit {' '.join(argv)} failed")
            r = {"pose_refine": refine, "steps_per_s": round(steps_per_second(run, a.skip), 3)}
            result["runs"].append(r)
            print(r, flush=True)
    for refine in ("off", "on"):
        v = [r["steps_per_s"] for r in result["runs"] if r["pose_refine"] == refine]
        result[f"steps_per_s_{refine}"] = round(sum(v) / len(v), 3)
    result["cost"] = round(result["steps_per_s_off"] / result["steps_per_s_on"], 3)
    path = ROOT / "benchmarks" / "results" / f"{a.name or 'pose_refine_speed_' + a.preset}.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
