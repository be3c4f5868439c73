"""How far a splat run's scene pulls its training cameras, checkpoint by checkpoint: every training photo's pose
solved (`--iterations` Levenberg-Marquardt iterations, models/splat/pose_solve.solve_corrections, as `--pose-solves`
does during training) against the Gaussians of each checkpoint, from the pose correction the checkpoint holds (zero
for a run without pose refinement), and the turn the solved poses keep against the photos' true poses, after the
similarity that best aligns the two sets (pose_residual.residual_shape: the mean turn per axis in each camera's own
frame is the turn every camera shares).

    python benchmarks/pose_pull.py RUN --checkpoints 400 800 1200 2000 --name NAME [--held-out N]

--held-out N: also each held-out photo's pose fitted to it against each checkpoint's Gaussians (N iterations,
pose_fit.fit_pose with its colour fitted, as `nerfkit eval --fit-poses N --fit-colour` does), from its given pose
moved with the training rig, and its angle from its true pose after the similarity that best aligns the
checkpoint's training poses to theirs: a photo the scene never saw, so the scene cannot have bent to its error.

RUN: a splat run on a procedural capture (benchmarks/corrections.py; the capture's truth/poses.npy, else its written
poses, are the truth). Writes benchmarks/results/NAME.json.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from pose_residual import residual_shape
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def solved_corrections(loaded, data, iterations: int, step: int) -> tuple[np.ndarray, np.ndarray]:
    """(the checkpoint's corrections [V, 6], the same after `iterations` LM iterations of each photo's pose) of a
    loaded splat run (RunFolder.load, its model bound to `data`) and its training frames `data`
    (training.setup.load_splits)."""
    from nerfkit.models.splat.gaussians import intrinsics_of
    from nerfkit.models.splat.pose_solve import solve_corrections
    from nerfkit.models.splat.train import schedule_at
    from nerfkit.rays.correction import camera_extent

    sc, poses = loaded.model.sc, np.asarray(data.poses, np.float64)
    held = np.asarray(loaded.params.get("cam_pose", np.zeros((len(poses), 6))), np.float32)
    solved = solve_corrections({**loaded.params, "cam_pose": held}, loaded.aux["active"], poses,
                               np.asarray(data.images), np.asarray([intrinsics_of(c) for c in data.cameras]),
                               camera_extent(poses), data.width, data.height, loaded.model.background,
                               schedule_at(step, 0.0, sc)["sh_degree"], sc.backend, sc.screen_dilation, iterations)
    return held, solved


def held_out_degrees(loaded, val, given, xi, truth, val_truth, iterations: int) -> list[float]:
    """Each held-out photo's angle (degrees) from its true pose (val_truth [M, 4, 4]) after its pose is fitted
    (module docstring) against the loaded run's Gaussians; given [V, 4, 4] and xi [V, 6] the training photos' given
    poses and corrections, truth [V, 4, 4] their true poses; val the held-out frames."""
    from nerfkit.rays.correction import (apply_similarity, pose_error, refined_poses, refinement_similarity,
                                         similarity_fit)

    to_truth = similarity_fit(refined_poses(given, xi), truth)
    start = apply_similarity(np.asarray(val.poses, np.float64), *refinement_similarity(given, xi))
    renderer = loaded.model.renderer()
    fitted = np.stack([renderer.fit_pose(loaded.params, loaded.aux, start[k], val.cameras[k], val.images[k],
                                         iterations, fit_colour=True)[0] for k in range(len(start))])
    return [round(float(x), 4) for x in pose_error(apply_similarity(fitted, *to_truth), val_truth)[0]]


def main() -> None:
    from nerfkit.data.procedural.scene import CAMERA_RADIUS
    from nerfkit.rays.correction import refined_poses
    from nerfkit.run.folder import RunFolder
    from nerfkit.training.setup import load_splits

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--checkpoints", type=int, nargs="+", required=True, help="steps of checkpoints the run kept")
    ap.add_argument("--iterations", type=int, default=3)
    ap.add_argument("--held-out", type=int, default=0, help="N > 0: also fit the held-out photos' poses (docstring)")
    ap.add_argument("--name", required=True)
    a = ap.parse_args()
    folder = RunFolder(a.run)
    cap_dir = folder.data_dir(None)
    capture, data, val, cfg = load_splits(cap_dir, folder.config(), False, lambda line: None)
    idx, val_idx = ([int(f.image.stem.split("_")[-1]) for f in capture.frames(spec)]
                    for spec in (cfg.data.train_split, cfg.data.val_split))
    given = np.asarray(data.poses, np.float64)
    # no truth/: the capture was written at the truth, and the normalised given poses are it
    truth_dir = cap_dir / "truth"
    truth = np.load(truth_dir / "poses.npy")[idx] if truth_dir.is_dir() else given
    val_truth = np.load(truth_dir / "poses.npy")[val_idx] if truth_dir.is_dir() else np.asarray(val.poses, np.float64)
    rows = []
    for step in a.checkpoints:
        loaded = folder.load(a.run / "checkpoints" / f"ckpt_{step:08d}.msgpack")
        loaded.model.bind_data(capture, data, log=lambda line: None)
        held, solved = solved_corrections(loaded, data, a.iterations, step)
        rows.append({"step": step, **{name: residual_shape(refined_poses(given, xi), truth, CAMERA_RADIUS)
                                      for name, xi in (("held", held), ("solved", solved))},
                     "moved_median_degrees": round(float(np.median(np.degrees(
                         np.linalg.norm(solved[:, :3] - held[:, :3], axis=1)))), 4)})
        if a.held_out:
            deg = held_out_degrees(loaded, val, given, held, truth, val_truth, a.held_out)
            rows[-1]["held_out"] = {"degrees": deg, "median_degrees": round(float(np.median(deg)), 4)}
        print(step, "shared turn held", rows[-1]["held"]["turn_mean_degrees"], "solved",
              rows[-1]["solved"]["turn_mean_degrees"], flush=True)
    result = {"what": __doc__.split("\n\n")[0], "run": str(a.run), "capture": str(cap_dir),
              "iterations": a.iterations, "held_out_iterations": a.held_out, "checkpoints": rows,
              "provenance": provenance()}
    path = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
