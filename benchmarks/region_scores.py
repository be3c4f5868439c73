"""Where on a held-out photo a splat run of a procedural capture loses: each photo's scored half split into the scene's
objects (the pixels whose centre ray meets a procedural surface: the photo's exact z-depth is under OBJECT_DEPTH) and
its far environment (every other pixel: the sphere around them), each scored as `nerfkit eval --fit-poses 10
--fit-colour` scores the photo (pose fitted, colour fitted on the left half, the right half scored). On the
capture's own held-out photos and on wide_holdout.py's photos midway between the ring's neighbours.

    python benchmarks/region_scores.py RUN [RUN ...] --name NAME [--cache DIR] [--sets held midway]

--sets held scores the five alone (a minute a run, where the forty take about five).

The renders are the ones `nerfkit eval` writes, 8-bit PNGs: their rounding puts a photo's PSNR 0.01-0.12 dB under
eval's (the more, the closer the render), the photo set's mean 0.02-0.06, alike for every run (both are in the
record). Writes benchmarks/results/NAME.json: per run and per photo set, the mean PSNR over the photos of the whole
scored half, of its objects and of its environment (each region's mean squared error over its pixels), and the same
per photo.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import wide_holdout
from wide_holdout import load_run, midway_poses

# The objects lie within SCENE_BOUNDS * sqrt(3) = 2.08 of the origin and the cameras CAMERA_RADIUS = 4 from it: z-depth
# at most 6.08. The environment's sphere (ENV_RADIUS = 12) is at least 8 away along a ray, z-depth at least 7.1 at the
# corner of a 40-degree view. Between the two: nothing (checked on every photo).
OBJECT_DEPTH, GAP = 6.6, (6.1, 7.1)


def midway_depths(cam, n: int, seed: int, supersample: int, cache: Path) -> np.ndarray:
    """[n, H, W] exact z-depth of wide_holdout.py's midway photos, cached beside them."""
    from nerfkit.data.procedural.captures import render_area

    path = cache / f"midway_depth_{n}_{seed}_{cam.width}x{cam.height}_ss{supersample}.npy"
    if not path.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        np.save(path, np.stack([render_area(c2w, cam, True, supersample)[2] for c2w in midway_poses(n, seed)])
                .astype(np.float32), allow_pickle=False)
    return np.load(path, allow_pickle=False)


def region_psnr(render: np.ndarray, photo: np.ndarray, objects: np.ndarray) -> dict:
    """PSNR of render against photo ([H, W, 3] in [0, 1]) on the right half of the columns (what --fit-colour
    scores): over all of it, over its pixels where objects [H, W] holds and over the rest (None for an empty
    region), and the objects' share of its pixels."""
    half = np.s_[:, photo.shape[1] // 2:]
    err = np.mean((render[half] - photo[half]) ** 2, axis=-1)
    obj = objects[half]

    def db(sel):
        return None if not sel.any() else round(float(-10.0 * np.log10(max(err[sel].mean(), 1e-12))), 3)

    return {"all": db(np.ones_like(obj)), "objects": db(obj), "environment": db(~obj),
            "object_share": round(float(obj.mean()), 4)}


def score_set(renderer, trained, data, bg, fit_poses: int, depths: np.ndarray) -> dict:
    """Score the photos of data as eval does (renders written to a scratch folder), then split each by region."""
    import imageio.v3 as iio

    from nerfkit.evaluation.evaluate import score_views

    if np.any((depths > GAP[0]) & (depths < GAP[1])):
        raise SystemExit("a photo has z-depths between the objects and the environment: not corrections.py's scene")
    with tempfile.TemporaryDirectory() as tmp:
        res = score_views(renderer, trained.params, trained.aux, data, 1, False, Path(tmp), bg, fit_poses, True)
        renders = [iio.imread(Path(tmp) / f"view_{k:03d}_rgb.png")[..., :3].astype(np.float32) / 255.0
                   for k in range(len(data))]
    per_view = []
    for k, (render, v) in enumerate(zip(renders, res["per_view"])):
        per_view.append({"name": v["name"], "psnr_eval": round(v["psnr"], 3),
                         **region_psnr(render, np.asarray(data.images[k]), depths[k] < OBJECT_DEPTH)})
    mean = {key: round(float(np.mean([v[key] for v in per_view if v[key] is not None])), 3)
            for key in ("psnr_eval", "all", "objects", "environment")}
    return {**mean, "per_view": per_view}


def score(run: Path, n: int, seed: int, supersample: int, cache: Path, fit_poses: int,
          sets: tuple = ("held", "midway")) -> dict:
    """The run's region scores on its capture's held-out photos ("held" in sets) and on the n midway photos
    ("midway"; module docstring)."""
    r = load_run(run, n, seed, supersample, cache)
    out = {}
    if "held" in sets:
        held_depths = np.stack([np.load(r.capture / "depth" / f"{Path(name).stem}.npy", allow_pickle=False)
                                for name in r.held.names])
        out["capture_held_out"] = score_set(r.renderer, r.trained, r.held, r.bg, fit_poses, held_depths)
    if "midway" in sets:
        out["midway"] = score_set(r.renderer, r.trained, r.midway, r.bg, fit_poses,
                                  midway_depths(r.midway.cameras[0], n, seed, supersample, cache))
    return out


def show(result: dict) -> list[dict]:
    return [{k: result[key][k] for k in ("psnr_eval", "all", "objects", "environment")} for key in result]


def options(ap) -> tuple[str, ...]:
    ap.add_argument("--sets", nargs="+", choices=("held", "midway"), default=["held", "midway"],
                    help="the photo sets to score: the capture's own held-out photos, the midway photos")
    return ("sets",)


if __name__ == "__main__":
    wide_holdout.main(__doc__, score, "region_scores", show, options)
