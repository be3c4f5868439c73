"""How well a mesh covers an object, seen from cameras: both ways, against silhouettes and depth.

For view k with silhouette S_k (alpha or mask > 1/2) and the mesh's coverage M_k (pixels whose
centre a triangle covers, raster.py):

    IoU_k = |M_k & S_k| / |M_k | S_k|,   precision_k = |M_k & S_k| / |M_k|,   recall_k = |M_k & S_k| / |S_k|

(an empty mesh scores 0, a mesh filling the image scores |S_k| / image: neither passes). Depth:
on the pixels both the mesh and the field cover (field opacity >= 1/2), the share where the mesh's
z-depth is within `tol` of the field's rendered z-depth (the expected depth given a hit; and its
median depth, where the running opacity reaches half the ray's opacity, render/volume.py: the
expected depth of a ray that grazes a soft edge and goes on to the floor lies on no surface, so
no mesh can match it there; or the exact depth, where known); and the same share on the
"interior" pixels only: more than EDGE_PX pixels from the silhouette's edge and from a jump of
the field's depth by more than `tol` between neighbours (where a sub-pixel shift of an edge swaps
a foreground depth for a background one).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from nerfkit.export.raster import mesh_depth

EDGE_PX = 2


def coverage_scores(covered: np.ndarray, silhouette: np.ndarray) -> dict:
    """IoU, precision and recall of one view's mesh coverage against its silhouette (bool [H, W] each)."""
    inter = float(np.sum(covered & silhouette))
    union = float(np.sum(covered | silhouette))
    return {"iou": inter / union if union else 1.0, "precision": inter / max(float(covered.sum()), 1.0),
            "recall": inter / max(float(silhouette.sum()), 1.0)}


def depth_agreement(depth: np.ndarray, reference: np.ndarray, valid: np.ndarray, tol: float) -> tuple[float, int]:
    """(share of the pixels where the mesh (depth < inf) and `valid` both hold whose |depth - reference|
    <= tol, number of such pixels)."""
    both = np.isfinite(depth) & valid
    n = int(both.sum())
    return (float(np.mean(np.abs(depth[both] - reference[both]) <= tol)) if n else 0.0), n


def interior_pixels(silhouette: np.ndarray, depth: np.ndarray, tol: float) -> np.ndarray:
    """bool [H, W]: pixels more than EDGE_PX from the silhouette's edge and from a jump of `depth`
    by more than tol between 4-neighbours."""
    jump = np.zeros(depth.shape, bool)
    dx = np.abs(np.diff(depth, axis=1)) > tol
    dy = np.abs(np.diff(depth, axis=0)) > tol
    jump[:, 1:] |= dx
    jump[:, :-1] |= dx
    jump[1:] |= dy
    jump[:-1] |= dy
    edge = silhouette ^ ndimage.binary_erosion(silhouette)
    near = ndimage.binary_dilation(edge | jump, iterations=EDGE_PX)
    return ~near


def mesh_against_views(verts: np.ndarray, faces: np.ndarray, poses: np.ndarray, cameras: list, silhouettes: list,
                       field_depth: list | None = None, field_opacity: list | None = None,
                       tol: float | None = None, field_median: list | None = None) -> dict:
    """Per-view IoU / precision / recall (and depth agreement within tol with the field's depth, when
    given: depth_within_tol, depth_within_tol_interior, and depth_within_tol_median with its median
    depth) of a mesh (normalised frame: verts [V, 3], faces [F, 3]) in views (poses [V, 4, 4], cameras,
    silhouettes bool [H, W]); with their means and minima."""
    rows = []
    for k, (pose, cam, sil) in enumerate(zip(poses, cameras, silhouettes)):
        d = mesh_depth(verts, faces, np.asarray(pose, np.float64), cam)
        row = coverage_scores(np.isfinite(d), sil)
        if field_depth is not None:
            valid = field_opacity[k] >= 0.5
            row["depth_within_tol"], row["depth_pixels"] = depth_agreement(d, field_depth[k], valid, tol)
            inner = valid & interior_pixels(sil, field_depth[k], tol)
            row["depth_within_tol_interior"], row["interior_pixels"] = depth_agreement(d, field_depth[k], inner, tol)
            if field_median is not None:
                row["depth_within_tol_median"], _ = depth_agreement(d, field_median[k], valid, tol)
        rows.append(row)
    out = {"views": rows}
    for key in rows[0] if rows else ():
        if key not in ("depth_pixels", "interior_pixels"):
            vals = [r[key] for r in rows]
            out[f"{key}_mean"], out[f"{key}_min"] = float(np.mean(vals)), float(np.min(vals))
    return out
