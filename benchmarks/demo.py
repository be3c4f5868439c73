"""The README's first command, timed as a user runs it: `nerfkit demo` with its defaults.

    python benchmarks/demo.py [--out runs/demo_bench]

Runs `nerfkit demo --out OUT` in its own process (procedural scene at 256x256, the demo preset's
3-minute budget, evaluation on the 10 test views, a 48-frame orbit, the report) and writes
benchmarks/results/demo.json: the whole command's wall clock, and the test PSNR / SSIM and steps from
the demo's own summary (OUT/demo_summary.json), with the commit it ran on.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("runs/demo_bench"))
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    record = {"what": "nerfkit demo (defaults), the whole command's wall clock", "provenance": provenance()}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "nerfkit", "demo", "--out", str(a.out), "--overwrite"], check=True)
    record["wall_minutes"] = round((time.perf_counter() - t0) / 60, 2)
    summary = json.loads((a.out / "demo_summary.json").read_text())
    record.update({k: summary[k] for k in ("steps", "steps_per_second", "test_psnr", "test_ssim", "minutes")})
    a.results.mkdir(parents=True, exist_ok=True)
    path = a.results / "demo.json"
    path.write_text(json.dumps(record, indent=2))
    print(f"nerfkit demo: {record['wall_minutes']} min, {record['steps']} steps, test PSNR {record['test_psnr']:.2f} dB, "
          f"SSIM {record['test_ssim']:.3f}; wrote {path}")


if __name__ == "__main__":
    main()
