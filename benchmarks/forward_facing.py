"""A forward-facing capture (every camera facing one way, as LLFF's phone captures): the procedural objects in
front of the far textured room, photographed from a grid of positions in one plane (make_capture(rig="forward")),
through the command line, preset against preset in one sitting.

    python benchmarks/forward_facing.py [--minutes 2] [--size 96] [--views 24] [--out runs/forward_facing]
        [--presets P ...] [--name procedural_forward] [--seed 0]

Runs (benchmarks/capture_cli.py; every 8th photo held out), by default: the splat preset (its far points drawn
through the photos' pixels, as for any forward-facing capture), the splat preset without far points, ngp (its
field in the NDC of the mean camera, as for any forward-facing capture) and ngp with the contraction instead
(--warp contract). Writes benchmarks/results/<name>_cli.json and .jpg.
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
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--out", type=Path, default=Path("runs/forward_facing"))
    ap.add_argument("--presets", nargs="+", default=["splat", "splat-nofar=--preset splat --far-points off", "ngp",
                                                      "ngp-contract=--preset ngp --warp contract"])
    ap.add_argument("--name", default="procedural_forward")
    ap.add_argument("--seed", type=int, default=0, help="the capture's seed (camera grid jitter and turns)")
    ap.add_argument("--results", type=Path, default=None, help="folder for the JSON (default benchmarks/results)")
    a = ap.parse_args()
    data = a.out / "capture"
    if not (data / "transforms.json").is_file():
        make_capture(data, "nerfstudio", n_views=a.views, size=a.size, environment=True, rig="forward",
                     seed=a.seed)
    capture_cli.main(["--data", str(data), "--name", a.name, "--minutes", f"{a.minutes:g}", "--downscale", "1",
                      "--out", str(a.out / "runs"), *(["--results", str(a.results)] if a.results else []),
                      "--presets", *a.presets])


if __name__ == "__main__":
    main()
