"""A splat run on a procedural ring capture scored on many more held-out photos than its capture holds out: a new
photo of the same scene (benchmarks/corrections.py's ring capture: the procedural scene with its environment,
rendered as the capture's photos are, supersampled, gain 1) midway between each two neighbours on the capture's
ring (the mean of their azimuths and of their elevations; procedural ring_poses), at its exact pose, given to the
run as the capture's held-out photos are (its pose in the capture's normalised frame, moved with the training rig
where the run refined its poses) and scored as `nerfkit eval --fit-poses 10 --fit-colour` scores them (pose fitted,
colour fitted on the left half, the right half scored). Five held-out photos (every 8th of 40) leave a mean that
one photo's poorly seen corner moves by a dB; this one is over the ring's 40 gaps, each seen from both sides.

    python benchmarks/wide_holdout.py RUN [RUN ...] --name NAME

The photos are rendered once (cached under --cache) and shared by every RUN, which must all be trained on captures
of the same size. Writes benchmarks/results/NAME.json: per run its mean PSNR and the per-photo PSNRs, and the same for
the capture's own held-out photos (as `nerfkit eval` scores them: corrections.py's eval_psnr_fitted_colour).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def midway_poses(n: int, seed: int) -> np.ndarray:
    """[n, 4, 4]: a camera midway between cameras k and k + 1 (mod n) of ring_poses(n, seed), k = 0 .. n - 1: the
    mean of their azimuths (the last gap's across 2 pi) and of their elevations, at the ring's radius."""
    from nerfkit.data.procedural import scene as proc
    from nerfkit.data.procedural.captures import ring_poses

    x, y, z = ring_poses(n, seed)[:, :3, 3].T
    az = np.unwrap(np.append(np.arctan2(y, x), np.arctan2(y[0], x[0])))  # the ring's azimuths, rising, the first again
    el = np.arcsin(z / np.sqrt(x * x + y * y + z * z))
    mid_az, mid_el = 0.5 * (az[:-1] + az[1:]), 0.5 * (el + np.roll(el, -1))
    return np.stack([proc.orbit_pose(a, e, proc.CAMERA_RADIUS) for a, e in zip(mid_az, mid_el)])


def photos(cam, n: int, seed: int, supersample: int, cache: Path) -> tuple[np.ndarray, np.ndarray]:
    """(midway_poses(n, seed), their photos [n, H, W, 3] in [0, 1] as the capture's are written: 8-bit)."""
    from nerfkit.data.procedural.captures import render_area

    poses = midway_poses(n, seed)
    path = cache / f"midway_{n}_{seed}_{cam.width}x{cam.height}_ss{supersample}.npy"
    if not path.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        shots = [np.round(np.clip(render_area(c2w, cam, True, supersample)[0], 0, 1) * 255) for c2w in poses]
        np.save(path, np.stack(shots).astype(np.uint8), allow_pickle=False)
    return poses, np.load(path, allow_pickle=False).astype(np.float32) / 255.0


@dataclasses.dataclass
class ScoredRun:
    """A corrections.py run loaded to be scored: its trained model, renderer and background, its capture's folder, its
    capture's own held-out photos (their poses as the run sees them) and the midway photos (as the run sees them)."""

    trained: object
    renderer: object
    bg: object
    capture: Path
    held: object
    midway: object


def load_run(run: Path, n: int, seed: int, supersample: int, cache: Path) -> ScoredRun:
    """Load run, a corrections.py run on a capture of n photos on ring_poses(n, seed), with its held-out photos and
    the n midway photos (their photos rendered once into cache), given to it as the capture's held-out photos are."""
    from nerfkit.core.viz import background_rgb
    from nerfkit.data.loader import load_frames, read_capture
    from nerfkit.data.normalize import apply_transform
    from nerfkit.render.images import make_renderer
    from nerfkit.run.folder import RunFolder

    folder = RunFolder(run)
    trained = folder.load(scene=False)
    cfg, d = trained.cfg, trained.cfg.data
    cap = read_capture(folder.data_dir(None), d.val_split, d.format, d.masks, d.holdout_every)
    held = load_frames(cap, d.val_split, downscale=d.downscale, target_width=d.target_width, background=d.background)
    cam = cap.frames(d.val_split)[0].camera
    if cam.params or held.width != cam.width:
        raise SystemExit(f"{run}: only full-size pinhole captures (corrections.py's) are scored")
    if len(cap.all_frames) != n:
        raise SystemExit(f"{run}: its capture has {len(cap.all_frames)} photos, not --views {n}")
    poses, images = photos(cam, n, seed, supersample, cache)
    given = apply_transform(held.transform, held.scale, poses).astype(np.float32)
    midway = dataclasses.replace(held, images=images, poses=trained.seen_from(d.val_split, given),
                                 cameras=[cam] * n, names=[f"wide_{k:03d}" for k in range(n)])
    return ScoredRun(trained, make_renderer(trained.model, cfg.train.chunk), background_rgb(d.background),
                     Path(folder.data_dir(None)),
                     dataclasses.replace(held, poses=trained.seen_from(d.val_split, held.poses)), midway)


def score(run: Path, n: int, seed: int, supersample: int, cache: Path, fit_poses: int) -> dict:
    """The run's scores on the n new photos of a capture of n photos on ring_poses(n, seed) (module docstring)."""
    from nerfkit.evaluation.evaluate import score_views

    r = load_run(run, n, seed, supersample, cache)
    res = score_views(r.renderer, r.trained.params, r.trained.aux, r.midway, 1, False, None, r.bg, fit_poses, True)
    per_view = [round(v["psnr"], 3) for v in res["per_view"]]
    own = score_views(r.renderer, r.trained.params, r.trained.aux, r.held, 1, False, None, r.bg, fit_poses, True)
    return {"psnr": round(res["psnr"], 3), "per_view": per_view, "median": round(float(np.median(per_view)), 3),
            "capture_held_out": {"names": r.held.names, "psnr": round(own["psnr"], 3),
                                 "per_view": [round(v["psnr"], 3) for v in own["per_view"]]}}


def main(doc: str = __doc__, scorer=score, name: str = "wide_holdout",
         show=lambda r: (r["psnr"], r["per_view"]), options=lambda ap: ()) -> None:
    """Score each RUN of the command line with scorer (this module's score, or region_scores.py's) and write the
    record NAME.json; show(result) is what is printed per run. options(ap) adds the scorer's own arguments and
    returns their names: they reach it as keywords, and the record."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--views", type=int, default=40, help="the capture's photos (corrections.py --views)")
    ap.add_argument("--seed", type=int, default=3, help="the capture's ring (corrections.SEED)")
    ap.add_argument("--supersample", type=int, default=4, help="as the capture was made (corrections.py --supersample)")
    ap.add_argument("--fit-poses", type=int, default=10)
    ap.add_argument("--cache", type=Path, default=Path("runs/wide_holdout"))
    ap.add_argument("--name", default=name)
    names = options(ap)
    a = ap.parse_args()
    own = {k: getattr(a, k) for k in names}
    result = {"what": doc.split("\n\n")[0], "views": a.views, "ring_seed": a.seed,
              "supersample": a.supersample, "fit_poses": a.fit_poses, **own, "runs": {}}
    for run in a.runs:
        result["runs"][str(run)] = r = scorer(run, a.views, a.seed, a.supersample, a.cache, a.fit_poses, **own)
        print(run, *show(r), flush=True)
    result["provenance"] = provenance()
    path = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
