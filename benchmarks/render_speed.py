"""Rendering speed of a trained run, compiled: one 800x800 frame and the viewer's 256x256, with a profile.

    python benchmarks/render_speed.py RUN_DIR [--data DIR] [--split "val[50:100]"] [--profile] [--slots N]
                                      [--repeats 3]

Renders view 0 of the split (the run's own data folder unless --data) at 800x800 and 256x256 with the
renderer `nerfkit render` uses (render.images.make_renderer), once to compile, then times the median of
--repeats (800) / --repeats + 2 (256) renders (on a shared machine, more repeats steady the median of a
fast renderer; the fastest is recorded too). Also prints the rounds and the samples the wavefront renderer shaded. With
--profile, one more 800x800 render runs under jax.profiler and the time per XLA operation kind (summed
over the render) is printed. --slots N: the wavefront renderer with N ray slots instead of make_renderer's
(more slots: fewer, larger rounds).
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import re
import statistics
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

from nerfkit.data.loader import load_frames, read_capture
from nerfkit.rays.cameras import Camera
from nerfkit.render.images import make_renderer
from nerfkit.run.folder import RunFolder


def timed(renderer, params, aux, c2w, camera, repeats: int) -> tuple[float, float]:
    """(median, fastest) seconds of `repeats` compiled renders."""
    renderer.render_camera(params, aux, c2w, camera)  # compile
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        renderer.render_camera(params, aux, c2w, camera)
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times)


# Python frames and executor bookkeeping (waits): left out, so the list is the XLA operations and transfers.
HOST_EVENTS = re.compile(r"^\$|ThunkExecutor|np\.asarray|Await|PjitFunction|CommonPjRt|ParseArguments")


def profile(renderer, params, aux, c2w, camera, top: int = 25) -> list[tuple[str, float, int]]:
    """(XLA op kind, total ms, count) of one render, heaviest first."""
    with tempfile.TemporaryDirectory() as tmp:
        jax.profiler.start_trace(tmp)
        renderer.render_camera(params, aux, c2w, camera)
        jax.profiler.stop_trace()
        events = json.load(gzip.open(glob.glob(f"{tmp}/**/*.trace.json.gz", recursive=True)[0]))["traceEvents"]
    total, count = collections.Counter(), collections.Counter()
    for e in events:
        if e.get("ph") == "X" and "dur" in e and not HOST_EVENTS.search(e["name"]):
            name = re.sub(r"\.\d+$", "", e["name"])
            total[name] += e["dur"] / 1e3
            count[name] += 1
    return [(k, v, count[k]) for k, v in total.most_common(top)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--split", default="val[50:100]")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--slots", type=int, default=None)
    ap.add_argument("--repeats", type=int, default=3, help="800x800 renders timed (256x256: this + 2)")
    ap.add_argument("--results", type=Path, default=Path(__file__).resolve().parent / "results" / "render_speed.json")
    a = ap.parse_args()

    run_ = RunFolder(a.run).load()

    cfg, model, params, aux, step = run_.cfg, run_.model, run_.params, run_.aux, run_.step
    data = load_frames(read_capture(RunFolder(a.run).data_dir(a.data), a.split), a.split)
    c2w, cam = data.poses[0], data.cameras[0]
    renderer = make_renderer(model, cfg.train.chunk)
    if a.slots and hasattr(renderer, "slots_for"):  # a wavefront renderer
        renderer = type(renderer)(model, a.slots)
    chunk = getattr(renderer, "chunk", None)  # ray renderers' batch; the splat rasteriser draws whole images
    print(f"{a.run} (step {step}), {type(renderer).__name__}, chunk {chunk}; jax {jax.__version__} on "
          f"{jax.devices()[0].platform}")
    results, fastest = {}, {}
    for side, repeats in ((800, a.repeats), (256, a.repeats + 2)):
        camera = Camera.pinhole(side, side, cam.fx * side / cam.width)
        results[side], fastest[side] = timed(renderer, params, aux, c2w, camera, repeats)
        print(f"{side}x{side}: {results[side]:.3f} s (median of {repeats}, compiled; fastest {fastest[side]:.3f})",
              flush=True)
    record = {"run": str(a.run), "step": step, "renderer": type(renderer).__name__, "chunk": chunk,
              "seconds_per_frame": {f"{k}x{k}": round(v, 4) for k, v in results.items()},
              "fastest_frame": {f"{k}x{k}": round(v, 4) for k, v in fastest.items()},
              "repeats_800": a.repeats,
              "what": "one compiled frame of the run's field (view 0 of the split), median of repeats"}
    if hasattr(renderer, "last_rounds"):
        camera = Camera.pinhole(800, 800, cam.fx * 800 / cam.width)
        renderer.render_camera(params, aux, c2w, camera)
        rounds, shaded = renderer.last_rounds, renderer.last_shaded
        print(f"800x800: {rounds} shading rounds with {renderer.slots_for(800 * 800)} ray slots, "
              f"{shaded / 1e6:.2f} M samples shaded ({shaded / 800**2:.1f} per pixel)")
        record.update({"rounds_800": rounds, "samples_shaded_800": shaded, "slots_800": renderer.slots_for(800 * 800)})
    if a.profile:
        camera = Camera.pinhole(800, 800, cam.fx * 800 / cam.width)
        print("\nprofile of one 800x800 render (ms summed over the render, count):")
        rows = profile(renderer, params, aux, c2w, camera)
        for name, ms, n in rows:
            print(f"  {ms:9.1f} ms {n:7d}x  {name[:80]}")
        record["profile_800_ms"] = [[name[:80], round(ms, 1), n] for name, ms, n in rows]
    from provenance import provenance

    record["provenance"] = provenance()
    a.results.parent.mkdir(parents=True, exist_ok=True)
    a.results.write_text(json.dumps(record, indent=1))
    print(f"wrote {a.results}")
    if not all(np.isfinite(v) for v in results.values()):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
