"""Meshes against exact surfaces: the procedural scene, trained and exported through the CLI, measured both
ways against its analytic solids, and for roughness by the normals.

    python benchmarks/mesh_procedural.py [--size 128] [--views 48] [--supersample 1] [--minutes 5] [--resolution 128]
                                         [--runs "splat=--preset splat --random-background on" ngp]
                                         [--out runs/mesh_procedural] [--skip-train] [--export-args "--taubin 0"]

Makes the procedural capture (SIZE px, VIEWS training views around it; --supersample S > 1: each pixel integrates
S x S samples, as a sensor does, where 1 point-samples the pixel centres), then per run LABEL[=ARGS] (ARGS default:
--preset LABEL; `exact`: see below) what a user types (--skip-train: only the export, of runs already there):

    nerfkit train SCENE ARGS --max-minutes M --out OUT/LABEL
    nerfkit export mesh OUT/LABEL --resolution R [EXPORT_ARGS]

and measures the mesh (data/procedural/surfaces.py's signed distance and normals; h = the grid cell, 2B / (R - 1)):

    accuracy       mean |sdf| of 200,000 points spread over the mesh by area                    (in cells h)
    completeness   mean distance from the true surface the training cameras see (traced at
                   their pixel centres) to the mesh's points                                   (in cells h)
    normals        over the mesh's points within 2 h of a true surface: the share whose face normal is within
                   10 degrees of the true normal there, and the median angle; and the same share over those at
                   least CREASE_CELLS h from a crease (surfaces.crease_distance: box edges, rims, where solids
                   meet), where a mesh on a grid of cell h can have the true normal at all
    normals seen   the same two shares over the points whose nearest true surface point a training camera sees
                   (in front of it, nothing between): the ground's underside and the solids' hidden parts are
                   meshed from no photo, so no normal there can be right but by chance

The run label `exact` (no training) fuses the training views' exact depth maps (ray traced, as wide as the
export renders them) with the export's own TSDF steps, its Taubin smoothing and its bilateral normal filtering
(`--taubin` and `--bilateral` of EXPORT_ARGS, or the export's defaults): what the grid and the fusion allow, the
ceiling of every measure above.

Writes benchmarks/results/mesh_procedural.json (with the commit) and mesh_procedural_<label>.png (the
export's picture of its mesh from two sides).
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from provenance import provenance

ROOT = Path(__file__).resolve().parents[1]
POINTS = 200_000
NORMAL_DEG = 10.0
CREASE_CELLS = 2.0
EXACT_BOUND = 1.5  # the box of the exact run: the trained runs' (the field's box of the procedural capture)


def nerfkit(*args: str) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "nerfkit", *args], stdout=subprocess.PIPE, text=True, check=False)
    print(r.stdout[-2000:], end="")
    if r.returncode:
        sys.exit(f"nerfkit {args[0]} failed")
    return time.perf_counter() - t0


def training_poses(scene: Path) -> np.ndarray:
    """The training cameras' c2w [C, 4, 4] (float64) of the capture in `scene`."""
    frames = json.loads((scene / "transforms_train.json").read_text())["frames"]
    return np.array([f["transform_matrix"] for f in frames], np.float64)


def seen_surface(poses: np.ndarray, size: int) -> np.ndarray:
    """The true surface points [N, 3] the training cameras c2w poses [C, 4, 4] see (exact ray tracing at their
    pixel centres)."""
    from nerfkit.data.procedural import scene as proc

    focal = 0.5 * size / np.tan(0.5 * proc.CAMERA_ANGLE_X)
    pts = []
    for pose in poses:
        o, d = proc.camera_rays(pose, size, size, focal)
        _, alpha, t = proc.trace(o, d)
        hit = alpha > 0.5
        pts.append(o[hit] + t[hit][:, None] * d[hit])
    return np.concatenate(pts)


def seen_by(q: np.ndarray, normal: np.ndarray, cams: np.ndarray, h: float) -> np.ndarray:
    """How many cameras [C, 3] see each true surface point q [N, 3] (outward normals [N, 3]): the point faces the
    camera, n . (c - q) > 0, and the ray from c towards q hits nothing before it, t > |q - c| - h / 2."""
    from nerfkit.data.procedural import scene as proc

    count = np.zeros(len(q), np.int32)
    for c in cams:
        d = q - c
        dist = np.linalg.norm(d, axis=1)
        _, alpha, t = proc.trace(np.broadcast_to(c, q.shape).copy(), d / dist[:, None])
        count += (np.sum(normal * (c - q), axis=1) > 0) & ((alpha < 0.5) | (t > dist - 0.5 * h))
    return count


def measure(mesh_file: Path, seen: np.ndarray, h: float, cams: np.ndarray) -> dict:
    import trimesh
    from scipy.spatial import cKDTree

    from nerfkit.data.procedural.surfaces import crease_distance, signed_distance, surface_normal

    mesh = trimesh.load(mesh_file, process=False)
    pts, fid = trimesh.sample.sample_surface(mesh, POINTS, seed=0)
    sdf = np.abs(signed_distance(pts))
    near = sdf < 2 * h
    true_n = surface_normal(pts[near])
    cos = np.sum(mesh.face_normals[fid[near]] * true_n, axis=1)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    off = crease_distance(pts[near]) >= CREASE_CELLS * h
    vis = seen_by(pts[near] - signed_distance(pts[near])[:, None] * true_n, true_n, cams, h) > 0
    gap = cKDTree(pts).query(seen)[0]
    return {"faces": len(mesh.faces), "accuracy_cells": float(sdf.mean() / h),
            "accuracy_median_cells": float(np.median(sdf) / h), "completeness_cells": float(gap.mean() / h),
            "completeness_median_cells": float(np.median(gap) / h), "near_share": float(near.mean()),
            "normals_within_10deg": float(np.mean(ang <= NORMAL_DEG)), "normal_median_deg": float(np.median(ang)),
            "normals_off_creases_within_10deg": float(np.mean(ang[off] <= NORMAL_DEG)),
            "off_crease_share": float(off.mean()), "seen_share": float(vis.mean()),
            "normals_seen_within_10deg": float(np.mean(ang[vis] <= NORMAL_DEG)),
            "normals_seen_off_creases_within_10deg": float(np.mean(ang[vis & off] <= NORMAL_DEG))}


def exact_mesh(poses: np.ndarray, resolution: int, out: Path, taubin: int, bilateral: int) -> float:
    """Fuses the exact depth maps of the training views c2w poses [C, 4, 4] (PIXELS_PER_CELL x resolution px) with
    export/tsdf.py's fused_surface, as tsdf_surface does its renders (the same truncation and smoothing), smooths it
    by `taubin` rounds and then `bilateral` rounds as the export does (surface.taubin_smooth,
    denoise.bilateral_smooth), writes the surface to `out`; returns the seconds taken."""
    import trimesh

    from nerfkit.data.procedural import scene as proc
    from nerfkit.export import tsdf
    from nerfkit.export.denoise import bilateral_smooth
    from nerfkit.export.grid import grid_axis
    from nerfkit.export.surface import taubin_smooth

    t0 = time.perf_counter()
    size = tsdf.PIXELS_PER_CELL * resolution
    focal = 0.5 * size / np.tan(0.5 * proc.CAMERA_ANGLE_X)
    c2w = poses.astype(np.float32)
    depth, alpha = [], []
    for pose in c2w:
        _, a, t = proc.trace(*proc.camera_rays(pose, size, size, focal))
        depth.append(np.where(a > 0.5, t, 0.0))
        alpha.append(a)
    depth, alpha = np.array(depth, np.float32), np.array(alpha, np.float32)
    intr = np.tile(np.array([focal, focal, size / 2, size / 2], np.float32), (len(c2w), 1))
    axis = grid_axis(EXACT_BOUND, resolution)
    h = float(axis[1] - axis[0])
    pixel = float(np.linalg.norm(c2w[0, :3, 3])) / focal  # a pixel's footprint at the scene centre
    verts, faces, *_ = tsdf.fused_surface(EXACT_BOUND, axis, c2w, intr, depth, alpha, tsdf.truncation(h, pixel),
                                          tsdf.SMOOTH_PIXELS * pixel / h, False)
    smooth = bilateral_smooth(taubin_smooth(verts, faces, taubin), faces, bilateral)
    trimesh.Trimesh(smooth, faces, process=False).export(out)
    return time.perf_counter() - t0


def smoothing_rounds(export_args: list[str]) -> tuple[int, int]:
    """(Taubin rounds, bilateral rounds) the export runs with these flags: those given, else its defaults."""
    from nerfkit.export.mesh import BILATERAL_ROUNDS, TAUBIN_PAIRS

    def given(flag, default):
        return int(export_args[export_args.index(flag) + 1]) if flag in export_args else default

    return given("--taubin", TAUBIN_PAIRS), given("--bilateral", BILATERAL_ROUNDS)


def summary(label: str, scores: dict, export_s: float) -> str:
    """One line of a run's measures."""
    return (f"{label}: accuracy {scores['accuracy_cells']:.2f} h, completeness {scores['completeness_cells']:.2f} h, "
            f"normals within {NORMAL_DEG:g} deg on {scores['normals_within_10deg']:.3f} (median "
            f"{scores['normal_median_deg']:.1f} deg; off creases {scores['normals_off_creases_within_10deg']:.3f}; "
            f"seen {scores['normals_seen_within_10deg']:.3f}, seen off creases "
            f"{scores['normals_seen_off_creases_within_10deg']:.3f}); export {export_s:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--views", type=int, default=48)
    ap.add_argument("--supersample", type=int, default=1, help="samples per pixel side of the photos (1: centres)")
    ap.add_argument("--minutes", type=float, default=5.0)
    ap.add_argument("--runs", nargs="+", default=["splat=--preset splat --random-background on", "ngp"])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "mesh_procedural")
    ap.add_argument("--skip-train", action="store_true", help="re-export and re-measure runs already in --out")
    ap.add_argument("--name", default="mesh_procedural")
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    ap.add_argument("--export-args", default="", help="more flags for nerfkit export mesh, e.g. \"--taubin 0\"")
    a = ap.parse_args()

    from nerfkit.data.procedural import scene as proc
    from nerfkit.data.procedural.scene import make_scene
    extra = shlex.split(a.export_args)
    taubin, bilateral = smoothing_rounds(extra)

    scene = a.out / ("scene" if a.supersample == 1 else f"scene_ss{a.supersample}")
    if not (scene / "transforms_train.json").is_file():
        make_scene(scene, size=a.size, n_train=a.views, n_val=4, n_test=4, supersample=a.supersample)
    poses = training_poses(scene)
    seen = seen_surface(poses, a.size)
    cams = poses[:, :3, 3]
    result = {"provenance": provenance(), "size": a.size, "views": a.views, "supersample": a.supersample,
              "minutes": a.minutes,
              "resolution": a.resolution, "export_args": a.export_args, "taubin": taubin, "bilateral": bilateral,
              "runs": {}}
    a.results.mkdir(parents=True, exist_ok=True)
    for entry in a.runs:
        preset, _, args = entry.partition("=")
        if preset == "exact":
            h = 2 * EXACT_BOUND / (a.resolution - 1)
            mesh = a.out / "exact.ply"
            export_s = exact_mesh(poses, a.resolution, mesh, taubin, bilateral)
            scores = measure(mesh, seen, h, cams)
            result["runs"][preset] = {"args": "exact depth maps", "export_wall_s": round(export_s, 1), "cell": h,
                                      **scores}
        else:
            args = args or f"--preset {preset}"
            run = a.out / preset
            train_s = None
            if not (a.skip_train and (run / "val_metrics.jsonl").is_file()):
                train_s = round(nerfkit("train", str(scene), "--out", str(run), *shlex.split(args), "--max-minutes",
                                        f"{a.minutes:g}", "--no-progress", "--overwrite"), 1)
            mesh = run / "exports" / "mesh.ply"
            export_s = nerfkit("export", "mesh", str(run), "--resolution", str(a.resolution), "--out", str(mesh),
                               "--no-progress", "--overwrite", *extra)
            rec = json.loads((run / "exports" / "export_mesh.json").read_text())
            h = 2 * rec["bound"] / (a.resolution - 1)
            val = [json.loads(line) for line in (run / "val_metrics.jsonl").read_text().splitlines() if line.strip()]
            scores = measure(mesh, seen, h, cams)
            result["runs"][preset] = {"args": args, "train_wall_s": train_s, "export_wall_s": round(export_s, 1),
                                      "cell": h, "pixel_cells": float(4.0 / (0.5 * a.size / np.tan(
                                          0.5 * proc.CAMERA_ANGLE_X)) / h),
                                      "val_psnr": val[-1]["psnr"], "step": val[-1]["step"], **scores}
            shutil.copyfile(run / "exports" / rec["picture"], a.results / f"{a.name}_{preset}.png")
        print(summary(preset, scores, export_s))
    (a.results / f"{a.name}.json").write_text(json.dumps(result, indent=1))
    print(f"wrote {a.results / f'{a.name}.json'}")


if __name__ == "__main__":
    main()
