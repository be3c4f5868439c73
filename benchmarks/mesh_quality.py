"""Meshes of a trained run against the held-out views, both ways: silhouette IoU, precision and recall,
and depth agreement with the field, for each export method, with the export's wall-clock time.

    python benchmarks/mesh_quality.py RUN --split "val[50:100]" [--methods tsdf levelset] [--name lego]
                                      [--watertight] [--texture] [--data DATA] [--export-args "--smooth 1"]

For each method M it runs what a user types, `nerfkit export mesh RUN --method M --out OUT/mesh_M.ply`
(timed: the whole process), reads the mesh back, moves it into the run's normalised frame and
rasterises it into every view of the split at the photos' size (export/raster.py). Against the
views' silhouettes (alpha or masks > 1/2): IoU, precision, recall per view (export/quality.py); against
the field's rendered z-depth, on pixels both cover: the share within 1% of the box's side 2B.
Writes benchmarks/results/mesh_<name>.json (with the commit), mesh_<name>.png (per method, four
views: green both, red mesh only, blue silhouette only) and mesh_<name>_<method>_sides.png (the
export's own picture of the mesh from two sides).
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

from nerfkit.run.folder import RunFolder

ROOT = Path(__file__).resolve().parents[1]


def export(run: Path, method: str, out: Path, extra: list[str]) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "nerfkit", "export", "mesh", str(run), "--method", method, "--out",
                        str(out), "--no-progress", "--overwrite", *extra], stdout=subprocess.PIPE, text=True, check=False)
    print(r.stdout, end="")
    if r.returncode:
        sys.exit(f"export failed: {method}")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--methods", nargs="+", default=["tsdf", "levelset"])
    ap.add_argument("--name", default=None)
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--watertight", action="store_true")
    ap.add_argument("--texture", action="store_true")
    ap.add_argument("--export-args", default="", help="more flags for nerfkit export mesh, e.g. \"--smooth 1\"")
    ap.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()

    import matplotlib.pyplot as plt
    import trimesh

    from nerfkit.export.carve import training_silhouettes
    from nerfkit.export.quality import mesh_against_views
    from nerfkit.export.raster import mesh_depth
    from nerfkit.render.images import make_renderer

    name = a.name or a.run.name
    run = RunFolder(a.run).load()
    sil = training_silhouettes(run, a.data, a.split)
    if sil is None:
        sys.exit("the capture has neither masks nor alpha: no silhouettes to measure against")
    poses, cams, silhouettes = sil
    renderer = make_renderer(run.model, run.cfg.train.chunk)
    t0 = time.perf_counter()
    field = [renderer.render_camera(run.params, run.aux, p, c, median=True) for p, c in zip(poses, cams)]
    print(f"rendered {len(field)} views of {a.split} in {time.perf_counter() - t0:.0f} s")
    tol = 0.01 * 2 * run.bound
    results = {"provenance": provenance(), "run": str(a.run), "split": a.split, "views": len(poses),
               "depth_tolerance": tol, "depth_tolerance_rule": "1% of the box side 2B (normalised units)",
               "export_args": a.export_args,
               "methods": {}}
    extra = (["--watertight"] if a.watertight else []) + (["--texture"] if a.texture else [])
    extra += shlex.split(a.export_args)
    fig, axes = plt.subplots(len(a.methods), 4, figsize=(12, 3 * len(a.methods)), squeeze=False)
    show = np.linspace(0, len(poses) - 1, 4).astype(int)
    for row, method in enumerate(a.methods):
        suffix = ".glb" if a.texture else ".ply"
        out = a.run / "exports" / f"mesh_{method}{suffix}"
        seconds = export(a.run, method, out, extra if method == "tsdf" else [e for e in extra if e != "--watertight"])
        record = json.loads((a.run / "exports" / "export_mesh.json").read_text())
        a.results.mkdir(parents=True, exist_ok=True)
        sides = a.results / f"mesh_{name}_{method}_sides.png"  # the export's own picture, from two sides
        shutil.copyfile(a.run / "exports" / record["picture"], sides)
        mesh = trimesh.load(out, process=False, force="mesh")
        verts = np.asarray(mesh.vertices, np.float64) @ run.transform[:3, :3].T + run.transform[:3, 3]
        faces = np.asarray(mesh.faces)
        scores = mesh_against_views(verts, faces, poses, cams, silhouettes, [f["depth_normalized"] for f in field],
                                    [f["opacity"] for f in field], tol, [f["depth_median"] for f in field])
        scores["closed_manifold"] = bool(mesh.is_watertight and mesh.is_winding_consistent)
        export_fields = {k: record[k] for k in ("resolution", "views", "every", "level") if k in record}
        results["methods"][method] = {"cli_seconds": round(seconds, 1), "export_seconds": record["seconds"],
                                      "export": export_fields, "vertices": len(mesh.vertices), "faces": len(faces),
                                      **scores}
        print(f"{method}: IoU mean {scores['iou_mean']:.4f} (min {scores['iou_min']:.4f}), precision "
              f"{scores['precision_mean']:.4f}, recall {scores['recall_mean']:.4f}; depth within {tol:.3g}: "
              f"{scores['depth_within_tol_median_mean']:.4f} (median depth), {scores['depth_within_tol_mean']:.4f} "
              f"(expected depth) of covered pixels, {scores['depth_within_tol_interior_mean']:.4f} "
              f"away from edges and depth jumps; the run's own silhouettes: IoU {scores['field_iou_mean']:.4f}, of "
              f"which the mesh covers {scores['recall_of_field_mean']:.4f}; {len(faces)} faces, closed "
              f"{scores['closed_manifold']}; {seconds:.0f} s")
        for col, k in enumerate(show):
            covered = np.isfinite(mesh_depth(verts, faces, poses[k], cams[k]))
            img = np.stack([covered & ~silhouettes[k], covered & silhouettes[k], silhouettes[k] & ~covered], -1)
            ax = axes[row, col]
            ax.imshow(img.astype(float))
            ax.set_title(f"{method} view {k}: IoU {scores['views'][k]['iou']:.3f}", fontsize=9)
            ax.axis("off")
    fig.suptitle(f"{name}: mesh coverage vs silhouettes (green both, red mesh only, blue silhouette only)")
    fig.tight_layout()
    a.results.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.results / f"mesh_{name}.png", dpi=80)
    (a.results / f"mesh_{name}.json").write_text(json.dumps(results, indent=1))
    print(f"wrote {a.results / f'mesh_{name}.json'}")


if __name__ == "__main__":
    main()
