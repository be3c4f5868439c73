"""Where a splat run starts, on the procedural unbounded capture (objects inside a far textured room, no masks,
exact poses): points triangulated at the given poses (what `nerfkit train` does for a posed capture without
points), exact surface points (the best start any SfM could give), and random points in the box. Each run
keeps the preset's other defaults (far points on: photos without masks).

    python benchmarks/splat_start.py [--minutes 2] [--size 96] [--views 40] [--points 20000] [--out runs/splat_start]

The two captures hold the same photos and poses; the second also has sparse_pc.ply with --points exact surface
points (make_capture(points=...)). The runs go through benchmarks/capture_cli.py (the CLI's wall clock, `nerfkit
eval` on the 5 held-out photos), which writes benchmarks/results/procedural_splat_start_cli.json and .jpg.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import capture_cli

from nerfkit.data.procedural.captures import make_capture


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=2.0)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--views", type=int, default=40)
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=Path("runs/splat_start"))
    a = ap.parse_args()
    given = a.out / "capture"
    exact = a.out / "capture_exact"
    for folder, points in ((given, 0), (exact, a.points)):
        if not (folder / "transforms.json").is_file():
            make_capture(folder, "nerfstudio", n_views=a.views, size=a.size, environment=True, points=points)
    capture_cli.main(["--data", str(given), "--name", "procedural_splat_start", "--minutes", f"{a.minutes:g}",
                      "--downscale", "1", "--out", str(a.out / "runs"), "--data-for", f"splat-exact={exact}",
                      "--presets", "splat", "splat-exact=--preset splat",
                      "splat-random=--preset splat --init-points random"])


if __name__ == "__main__":
    main()
