"""Frame time of a baked scene's WebGL page in headless Chromium (software WebGL2: SwiftShader).

    python benchmarks/bake_web_frametime.py BAKED_DIR [--sizes 800 400] [--frames 3] [--screenshot shot.png]
                                            [--json benchmarks/results/bake_lego_web.json]

Serves BAKED_DIR (a `nerfkit bake` output) with nerfkit.bake.web.start_server, always with the
package's current page and without writing into the folder, opens it in headless Chromium with
the WebGL flags of tests/chromium.py, and times window.nerfkitBaked.benchmark: --frames renders of
the default orbit camera at each size, each frame synchronised by a pixel read-back (after one
warm-up frame). Prints one line per size and a JSON summary; --screenshot saves the page (the
on-screen view at the window's size) as PNG, --json writes the summary with its provenance. On a real GPU the same page is far faster: the
numbers here are a CPU (SwiftShader) lower bound that needs no GPU to reproduce.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from chromium import WEBGL_ARGS, Chromium, find_chromium
from provenance import provenance

from nerfkit.bake.web import scene_mb, start_server, stop_server


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("baked", type=Path, help="a baked scene folder (nerfkit bake RUN --out DIR)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[800, 400], help="square frame sizes, pixels")
    ap.add_argument("--frames", type=int, default=3, help="timed frames per size")
    ap.add_argument("--screenshot", type=Path, default=None, help="save a PNG of the page here")
    ap.add_argument("--json", type=Path, default=None, help="write the summary (with provenance) here")
    ap.add_argument("--window", type=int, nargs=2, default=[800, 800], metavar=("W", "H"), help="browser window")
    a = ap.parse_args()
    binary = find_chromium()
    if binary is None:
        print("no Chromium found (apt-get install chromium, or set $NERFKIT_CHROMIUM)", file=sys.stderr)
        return 1
    server, url = start_server(a.baked, write_page=False)
    results = {"scene": str(a.baked), "mb": round(scene_mb(a.baked), 2), "chromium_flags": list(WEBGL_ARGS),
               "frames": a.frames, "ms_per_frame": {}}
    with tempfile.TemporaryDirectory(prefix="nerfkit-bench-chromium-") as profile:
        browser = Chromium(binary, Path(profile), *a.window, webgl=True)
        try:
            browser.open_page()
            t0 = time.perf_counter()
            browser.navigate(url)
            info = browser.evaluate("window.nerfkitBaked.ready", timeout=300)
            results["load_s"] = round(time.perf_counter() - t0, 2)
            results["renderer"] = browser.evaluate(
                "(() => { const gl = document.createElement('canvas').getContext('webgl2');"
                " const e = gl.getExtension('WEBGL_debug_renderer_info');"
                " return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); })()")
            results.update({k: info[k] for k in ("bricks", "resolution", "sh_bands", "atlas")})
            print(f"{a.baked}: {info['bricks']} bricks, {info['mb']:.1f} MB, loaded in {results['load_s']} s; "
                  f"{results['renderer']}")
            for size in a.sizes:
                ms = browser.evaluate(f"window.nerfkitBaked.benchmark({{width: {size}, height: {size}, "
                                      f"frames: {a.frames}}})", timeout=600)
                results["ms_per_frame"][f"{size}x{size}"] = round(ms, 1)
                print(f"{size}x{size}: {ms:.1f} ms/frame ({1000 / ms:.2f} fps)", flush=True)
            if a.screenshot:
                browser.evaluate("window.nerfkitBaked.draw()", timeout=600)
                browser.screenshot(a.screenshot)
                print(f"wrote {a.screenshot}")
        finally:
            browser.close()
            stop_server(server)
    print(json.dumps(results))
    if a.json:
        a.json.write_text(json.dumps({**results, "provenance": provenance()}, indent=2))
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
