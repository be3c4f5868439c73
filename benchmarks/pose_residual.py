"""The shape of what pose refinement leaves: each training photo's refined pose against the truth, after the
similarity that best aligns the refined set to the true one (rays/correction.aligned_pose_error), in the camera's
own frame: the turn w (degrees about the camera's x, y, z axes: pitch, yaw, roll) and the centre's offset t (in
units of the camera radius, along the same axes).

    python benchmarks/pose_residual.py RUN --name NAME     (RUN: a corrections.py run folder, e.g. /tmp/c/pose)

Writes benchmarks/results/NAME.json: the median angle; the rms and the mean of w per axis (a mean is a turn every
camera shares in its own frame); the median angle with that shared turn taken out; the correlation of each turn
with the shift that keeps the scene's centre in view (w_x with t_y, w_y with t_x: a camera moved on its orbit about
the centre); the rms of t per axis. The same figures for the given poses beside them.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]


def residual_shape(refined: np.ndarray, truth: np.ndarray, radius: float) -> dict:
    """The figures of the module docstring for refined and true poses [N, 4, 4] (radius: the camera radius)."""
    from nerfkit.rays.correction import apply_similarity, pose_error, similarity_fit

    aligned = apply_similarity(refined, *similarity_fit(refined, truth))
    rel = np.einsum("nji,njk->nik", truth[:, :3, :3], aligned[:, :3, :3])
    w = np.degrees(np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]],
                            -1) / 2)
    t = np.einsum("nji,nj->ni", truth[:, :3, :3], aligned[:, :3, 3] - truth[:, :3, 3]) / radius
    r3 = lambda v: [round(float(x), 4) for x in v]  # noqa: E731
    return {"median_degrees": round(float(np.median(pose_error(aligned, truth)[0])), 4),
            "turn_rms_degrees": r3(np.sqrt((w ** 2).mean(0))), "turn_mean_degrees": r3(w.mean(0)),
            "median_degrees_shared_turn_out": round(float(np.median(np.linalg.norm(w - w.mean(0), axis=1))), 4),
            "shift_rms_radius_share": r3(np.sqrt((t ** 2).mean(0))),
            "orbit_correlation": {"pitch_with_shift_y": round(float(np.corrcoef(w[:, 0], t[:, 1])[0, 1]), 3),
                                  "yaw_with_shift_x": round(float(np.corrcoef(w[:, 1], t[:, 0])[0, 1]), 3)}}


def main() -> None:
    from nerfkit.data.loader import read_capture, scene_cameras
    from nerfkit.data.procedural.scene import CAMERA_RADIUS
    from nerfkit.rays.correction import refined_poses
    from nerfkit.run.folder import RunFolder

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--name", required=True)
    a = ap.parse_args()
    folder = RunFolder(a.run)
    loaded, cap_dir = folder.load(), folder.data_dir(None)
    cap = read_capture(cap_dir, "train")
    idx = [int(f.image.stem.split("_")[-1]) for f in cap.frames("train")]
    given = np.asarray(scene_cameras(cap, "train").poses, np.float64)
    truth = np.load(cap_dir / "truth" / "poses.npy")[idx] if (cap_dir / "truth").is_dir() else given
    refined = refined_poses(given, np.asarray(loaded.params["cam_pose"]))
    result = {"what": __doc__.split("\n\n")[0], "run": str(a.run), "capture": str(cap_dir),
              "photos": len(idx), "refined": residual_shape(refined, truth, CAMERA_RADIUS),
              "given": residual_shape(given, truth, CAMERA_RADIUS), "provenance": provenance()}
    path = ROOT / "benchmarks" / "results" / f"{a.name}.json"
    path.write_text(json.dumps(result, indent=2))
    print(json.dumps(result["refined"]), f"\nwrote {path}")


if __name__ == "__main__":
    main()
