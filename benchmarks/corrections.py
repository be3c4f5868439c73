"""Per-photo corrections of the splat method (--appearance, --pose-refine) on procedural captures whose photos
were taken with per-photo gains at poses off the written ones by a known amount; the same capture with exact poses
and no gains is the reference.

    python benchmarks/corrections.py [--steps 2000] [--size 64] [--masks] [--name corrections_procedural]

For each variant (exact: the exact capture, corrections off; none: the imperfect capture, corrections off;
colour, pose, both), one run of `nerfkit train --preset splat` with --max-steps, then:
    held-out PSNR (the run's last validation: every held-out photo, at its written pose and with the
    mean colour transform; the imperfect capture's held-out photos have their own pose errors and gains),
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

import jax.numpy as jnp
import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]

VARIANTS = {"exact": ("exact", ["--appearance", "off"]), "none": ("imperfect", ["--appearance", "off"]),
            "colour": ("imperfect", ["--appearance", "on"]),
            "pose": ("imperfect", ["--appearance", "off", "--pose-refine", "on"]),
            "both": ("imperfect", ["--appearance", "on", "--pose-refine", "on"])}


def main() -> None:
    from nerfkit.cli.main import main as nerfkit
    from nerfkit.data.loader import read_capture
    from nerfkit.data.procedural.captures import make_capture
    from nerfkit.data.procedural.scene import CAMERA_RADIUS
    from nerfkit.rays.correction import aligned_pose_error, corrected_pose
    from nerfkit.run.folder import RunFolder

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--views", type=int, default=40)
    ap.add_argument("--masks", action="store_true", help="objects on a backdrop with masks (else a far environment)")
    ap.add_argument("--degrees", type=float, default=1.0)
    ap.add_argument("--shift", type=float, default=0.02, help="pose error as a fraction of the camera radius")
    ap.add_argument("--gains", type=float, default=0.15)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--out", type=Path, default=Path("runs/corrections"))
    ap.add_argument("--name", default="corrections_procedural")
    a = ap.parse_args()
    caps = {}
    for kind in ("exact", "imperfect"):
        noisy = kind == "imperfect"
        caps[kind] = make_capture(a.out / f"cap_{kind}", "nerfstudio", n_views=a.views, size=a.size, seed=3,
                                  environment=not a.masks, masks=a.masks,
                                  pose_noise=(a.degrees, a.shift) if noisy else (0.0, 0.0),
                                  gains=a.gains if noisy else 0.0)
    truth_poses = np.load(caps["imperfect"] / "truth" / "poses.npy")
    truth_gains = np.load(caps["imperfect"] / "truth" / "gains.npy")
    result = {"what": __doc__.split("\n\n")[0], "steps": a.steps, "size": a.size, "views": a.views, "masks": a.masks,
              "pose_noise_degrees": a.degrees, "pose_noise_radius_share": a.shift, "gains": a.gains, "runs": {},
              "provenance": provenance()}
    init = [] if a.masks else ["--init-points", "random"]  # the procedural textures give SfM a few dozen points
    for name in a.variants:
        kind, flags = VARIANTS[name]
        run = a.out / name
        argv = ["train", str(caps[kind]), "--out", str(run), "--preset", "splat", "--max-steps", str(a.steps),
                "--val-every", str(a.steps), "--ckpt-every", str(a.steps), "--capacity", "20000", "--no-progress",
                "--overwrite", *init, *flags]
        if nerfkit(argv) != 0:
            raise SystemExit(f"nerfkit {' '.join(argv)} failed")
        val = [json.loads(x) for x in (run / "val_metrics.jsonl").read_text().splitlines()][-1]
        loaded = RunFolder(run).load()
        idx = [int(f.image.stem.split("_")[-1]) for f in read_capture(caps[kind], "train").frames("train")]
        poses = np.asarray(loaded.scene["train_poses"], np.float64)
        r = {"flags": " ".join(flags), "val_psnr": round(val["psnr"], 3)}
        if kind == "imperfect":
            given = aligned_pose_error(poses, truth_poses[idx])
            r["given_pose_error"] = {"degrees": round(given[0], 4), "radius_share": round(given[1] / CAMERA_RADIUS, 5)}
            if "cam_pose" in loaded.params:
                refined = np.asarray(corrected_pose(jnp.asarray(poses, jnp.float32), loaded.params["cam_pose"],
                                                    loaded.model.extent), np.float64)
                after = aligned_pose_error(refined, truth_poses[idx])
                r["refined_pose_error"] = {"degrees": round(after[0], 4),
                                           "radius_share": round(after[1] / CAMERA_RADIUS, 5)}
            gains = truth_gains[idx] / truth_gains[idx].mean(0)
            r["identity_gain_error"] = round(float(np.median(np.abs(gains - 1.0))), 4)
            if "cam_color" in loaded.params:
                diag = 1.0 + np.einsum("vii->vi", np.asarray(loaded.params["cam_color"])[:, :, :3])
                r["gain_error"] = round(float(np.median(np.abs(diag / diag.mean(0) - gains))), 4)
        result["runs"][name] = r
        print(name, r, flush=True)
    path = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
