"""Per-photo corrections (--pose-refine; the splat method's colour transforms --appearance, the fields' appearance
embeddings --appearance-dim) on procedural captures whose photos were taken with per-photo gains at poses off the
written ones by a known amount; the same capture with exact poses and no gains is the reference.

    python benchmarks/corrections.py [--preset splat] [--steps 2000] [--size 64] [--masks] [--name NAME]
        [--rig ring|forward] [--supersample S] [--held-out exact|imperfect] [--random-start | --points N]
        [--flags "..."] [--fit-poses N] [--fit-colour]

For each variant (exact: the exact capture, corrections off; none: the imperfect capture, corrections off;
colour, pose, both), one run of `nerfkit train --preset P` with --max-steps (splats: 20,000 slots, starting from
points triangulated at the given poses as any posed capture without points does, or --random-start, or N exact
surface points with --points N: a start as good as triangulation on this scene that needs no pycolmap), then:
    held-out PSNR: the run's last validation (every held-out photo at its written pose, with the mean colour
    transform or embedding) and `nerfkit eval`'s (the same, but where poses were refined, from the written poses
    moved by the similarity that maps the given training poses onto the refined ones); the imperfect capture's
    held-out photos (every 8th) are taken and written at their exact poses with gain 1 (--held-out exact, BARF's
    protocol: the score measures the scene learned), or have pose errors and gains of their own (imperfect: the
    score is then bounded by their own errors, whatever the training learned); with --fit-poses N also after
    each held-out photo's pose is fitted to it against the frozen scene (`nerfkit eval --fit-poses N`, splats),
    with --fit-colour also on the right half of each held-out photo after its colour is fitted on the left half
    (`nerfkit eval --fit-colour`: eval_psnr_fitted_colour, and the same halves before the colour map),
    the training poses' median error against the truth in degrees and in units of the camera radius (4),
    before and after refinement, after the similarity that best aligns the camera centres (the frame is free),
    the gains' median error (each photo's colour-transform diagonal relative to their mean, against the true
    gains relative to theirs; identity's error for comparison).
Writes benchmarks/results/<name>.json with its provenance.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]

VARIANTS = {"exact": ("exact", ["colour-off"]), "none": ("imperfect", ["colour-off"]),
            "colour": ("imperfect", ["colour-on"]),
            "pose": ("imperfect", ["colour-off", "--pose-refine", "on"]),
            "both": ("imperfect", ["colour-on", "--pose-refine", "on"])}
SEED = 3  # the captures' poses, gains and pose errors (make_capture's seed)
COLOUR = {"splat": {"colour-off": ["--appearance", "off"], "colour-on": ["--appearance", "on"]},
          "fields": {"colour-off": ["--appearance-dim", "0"], "colour-on": ["--appearance-dim", "16"]}}


def flags_of(names: list[str], preset: str) -> list[str]:
    table = COLOUR["splat" if preset == "splat" else "fields"]
    return [x for n in names for x in table.get(n, [n])]


def main() -> None:
    import jax

    from nerfkit.cli.main import main as nerfkit
    from nerfkit.data.loader import read_capture, scene_cameras
    from nerfkit.data.procedural.captures import make_capture, rig_poses
    from nerfkit.data.procedural.scene import CAMERA_RADIUS
    from nerfkit.evaluation.evaluate import evaluate_run
    from nerfkit.rays.correction import aligned_pose_error, refined_poses
    from nerfkit.run.folder import RunFolder

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--preset", default="splat")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--views", type=int, default=40)
    ap.add_argument("--supersample", type=int, default=1,
                    help="S: each photo's pixels integrate S x S samples, as a sensor does (1: point-sampled, aliased)")
    ap.add_argument("--masks", action="store_true", help="objects on a backdrop with masks (else a far environment)")
    ap.add_argument("--rig", choices=("ring", "forward"), default="ring",
                    help="cameras all around the objects, or all facing one way (LLFF's forward-facing captures)")
    ap.add_argument("--degrees", type=float, default=1.0)
    ap.add_argument("--shift", type=float, default=0.02, help="pose error as a fraction of the camera radius")
    ap.add_argument("--gains", type=float, default=0.15)
    ap.add_argument("--held-out", choices=("exact", "imperfect"), default="exact",
                    help="held-out photos at their exact poses and gains (BARF's protocol: their score measures the "
                         "scene learned) or with errors of their own, as the training photos")
    ap.add_argument("--random-start", action="store_true",
                    help="splats: random points (else triangulated at the given poses, as any posed capture)")
    ap.add_argument("--points", type=int, default=0,
                    help="N > 0: the captures hold N exact surface points (make_capture(points=N), sparse_pc.ply) that "
                         "splats start from, instead of points triangulated at the given poses")
    ap.add_argument("--flags", default="", help="more `nerfkit train` flags for every variant, e.g. \"--sh-degree 0\"")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--fit-poses", type=int, default=0,
                    help="N > 0: also score the held-out photos after fitting each one's pose to it against the "
                         "frozen scene (`nerfkit eval --fit-poses N`; splats)")
    ap.add_argument("--fit-colour", action="store_true",
                    help="also score the held-out photos with each one's colour fitted on its left half and the right "
                         "half scored (`nerfkit eval --fit-colour`, with --fit-poses N when given)")
    ap.add_argument("--out", type=Path, default=Path("runs/corrections"))
    ap.add_argument("--name", default="corrections_procedural")
    a = ap.parse_args()
    if a.random_start and a.points:
        ap.error("--random-start and --points name two different starts: give one")
    caps = {}
    for kind in ("exact", "imperfect"):
        noisy = kind == "imperfect"
        caps[kind] = make_capture(a.out / f"cap_{kind}", "nerfstudio", n_views=a.views, size=a.size, seed=SEED,
                                  environment=not a.masks, masks=a.masks,
                                  pose_noise=(a.degrees, a.shift) if noisy else (0.0, 0.0),
                                  gains=a.gains if noisy else 0.0, exact_every=8 if a.held_out == "exact" else 0,
                                  supersample=a.supersample, rig=a.rig, points=a.points)
    truth = caps["imperfect"] / "truth"
    if truth.is_dir():
        truth_poses, truth_gains = np.load(truth / "poses.npy"), np.load(truth / "gains.npy")
    else:  # --degrees 0 --shift 0 --gains 0: written at the truth (refinement's own drift away from it)
        truth_poses, truth_gains = rig_poses(a.rig, a.views, seed=SEED), np.ones((a.views, 3))
    result = {"what": __doc__.split("\n\n")[0], "preset": a.preset, "steps": a.steps, "size": a.size, "views": a.views, "masks": a.masks,
              "supersample": a.supersample, "rig": a.rig,
              "pose_noise_degrees": a.degrees, "pose_noise_radius_share": a.shift, "gains": a.gains,
              "held_out": a.held_out, "flags": a.flags, "runs": {}, "provenance": provenance(),
              "start": "random" if a.random_start else f"{a.points} exact points" if a.points else "auto",
              "device": jax.devices()[0].device_kind}
    extra = []
    if a.preset == "splat":
        extra = (["--init-points", "random"] if a.random_start else []) + ["--capacity", "20000"]
    extra += a.flags.split()
    for name in a.variants:
        kind, names = VARIANTS[name]
        flags = flags_of(names, a.preset)
        run = a.out / name
        argv = ["train", str(caps[kind]), "--out", str(run), "--preset", a.preset, "--max-steps", str(a.steps),
                "--val-every", str(a.steps), "--ckpt-every", str(a.steps), "--no-progress", "--overwrite", *extra,
                *flags]
        if nerfkit(argv) != 0:
            raise SystemExit(f"nerfkit {' '.join(argv)} failed")
        val = [json.loads(x) for x in (run / "val_metrics.jsonl").read_text().splitlines()][-1]
        loaded = RunFolder(run).load()
        idx = [int(f.image.stem.split("_")[-1]) for f in read_capture(caps[kind], "train").frames("train")]
        poses = np.asarray(scene_cameras(read_capture(caps[kind], "train"), "train").poses, np.float64)
        ev = evaluate_run(run, None, loaded.cfg.data.val_split, progress=False, write=False)
        r = {"flags": " ".join(flags), "steps_done": val["step"], "train_s": val["elapsed"], "val_psnr": round(val["psnr"], 3), "eval_psnr": round(ev["psnr"], 3)}
        if a.fit_poses and loaded.model.supports.fit_poses:
            fit = evaluate_run(run, None, loaded.cfg.data.val_split, progress=False, write=False,
                               fit_poses=a.fit_poses)
            r["eval_psnr_fitted_poses"] = round(fit["psnr"], 3)
        if a.fit_colour:
            fit_poses = a.fit_poses if loaded.model.supports.fit_poses else 0
            col = evaluate_run(run, None, loaded.cfg.data.val_split, progress=False, write=False, fit_poses=fit_poses,
                               fit_colour=True)
            r["eval_psnr_fitted_colour"] = round(col["psnr"], 3)
            r["eval_psnr_fitted_colour_unmapped"] = round(float(np.mean([v["colour_fit"]["psnr_unfitted"]
                                                                         for v in col["per_view"]])), 3)
        if "poses" in ev:
            r["eval_poses"] = ev["poses"]
        if kind == "imperfect":
            given = aligned_pose_error(poses, truth_poses[idx])
            r["given_pose_error"] = {"degrees": round(given[0], 4), "radius_share": round(given[1] / CAMERA_RADIUS, 5)}
            if "cam_pose" in loaded.params:
                refined = refined_poses(poses, loaded.params["cam_pose"])
                after = aligned_pose_error(refined, truth_poses[idx])
                r["refined_pose_error"] = {"degrees": round(after[0], 4),
                                           "radius_share": round(after[1] / CAMERA_RADIUS, 5)}
            gains = truth_gains[idx] / truth_gains[idx].mean(0)
            r["identity_gain_error"] = round(float(np.median(np.abs(gains - 1.0))), 4)
            if "cam_color" in loaded.params:  # splats' colour transforms (the fields' embeddings have no gain)
                diag = 1.0 + np.einsum("vii->vi", np.asarray(loaded.params["cam_color"])[:, :, :3])
                r["gain_error"] = round(float(np.median(np.abs(diag / diag.mean(0) - gains))), 4)
        result["runs"][name] = r
        print(name, r, flush=True)
    path = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
