"""Frame time of a splat run's baked WebGL page in headless Chromium (software WebGL2: SwiftShader).

    python benchmarks/splat_web_frametime.py PAGE_DIR [--sizes 800 400] [--frames 3] [--screenshot shot.png]

PAGE_DIR is `nerfkit bake SPLAT_RUN --out PAGE_DIR`. Serves it with nerfkit.bake.web.start_server, opens it in
headless Chromium with the WebGL flags of tests/chromium.py and times window.nerfkitSplat.benchmark: --frames
frames of the page's start camera at each size (CPU depth sort + draw + a 1-pixel read-back that waits for the
GPU), after a warm-up frame. Prints one line per size and writes benchmarks/results/splat_web_<name>.json. On a
real GPU the same page is far faster: these are CPU (SwiftShader) numbers that need no GPU to reproduce.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from chromium import Chromium, find_chromium  # noqa: E402
from provenance import provenance  # noqa: E402

from nerfkit.bake.web import scene_mb, start_server, stop_server  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("page", type=Path)
    ap.add_argument("--sizes", type=int, nargs="+", default=[800, 400])
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--screenshot", type=Path, default=None)
    ap.add_argument("--name", default=None, help="result name (default: the page folder's name)")
    a = ap.parse_args()
    binary = find_chromium()
    if binary is None:
        print("no Chromium found", file=sys.stderr)
        return 1
    server, url = start_server(a.page)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        browser = Chromium(binary, Path(tmp) / "profile", 900, 900, webgl=True)
        try:
            browser.open_page()
            browser.navigate(url)
            info = browser.evaluate("window.nerfkitSplat.ready", timeout=300)
            for size in a.sizes:
                ms = browser.evaluate(f"window.nerfkitSplat.benchmark({{size: {size}, frames: {a.frames}}})",
                                      timeout=600)
                rows.append({"size": size, "ms": [round(x, 1) for x in ms], "min_ms": round(min(ms), 1)})
                print(f"{size}x{size}: {min(ms):.0f} ms/frame (min of {len(ms)}; {info['count']} Gaussians)",
                      flush=True)
            if a.screenshot:
                browser.evaluate("window.nerfkitSplat.draw()", timeout=600)
                browser.screenshot(a.screenshot)
        finally:
            browser.close()
            stop_server(server)
    result = {"what": "splat page frame time, headless Chromium, SwiftShader (CPU) WebGL2", "page": str(a.page),
              "gaussians": info["count"], "mb": round(scene_mb(a.page), 2), "sizes": rows,
              "provenance": provenance()}
    out = Path(__file__).resolve().parent / "results" / f"splat_web_{a.name or a.page.name}.json"
    out.write_text(json.dumps(result, indent=2))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
