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

Roughness, on the same interior pixels: the angle between the normal of the mesh's face seen there and
the normal of the field's median depth map, n_d = (P(i, j + s) - P(i, j - s)) x (P(i + s, j) - P(i - s, j))
for the back-projected pixels P and a baseline of s = NORMAL_STEP pixels either side (normal_agreement:
the share within NORMAL_DEG and the median angle). On the mesh alone (mesh_roughness): the median angle
between the normals of faces that share an edge (a crumpled surface of facets has a large one), and the
share of faces in small disconnected pieces (under SMALL_PIECE of the faces each).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from nerfkit.export.raster import mesh_depth, rasterize
from nerfkit.rays.cameras import camera_rays, project_points

EDGE_PX = 2
NORMAL_STEP = 2  # pixels either side for the depth map's normals
NORMAL_DEG = 10.0  # normals agree within this angle
SMALL_PIECE = 0.01  # a connected piece with under this share of the faces is small


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
    """Per-view IoU / precision / recall (and, when the field's depth is given: depth agreement within tol with
    it, depth_within_tol, depth_within_tol_interior, and depth_within_tol_median with its median depth; the
    field's own silhouette (opacity >= 1/2) against the view's, field_iou and field_recall; the share of the
    field's silhouette the mesh covers, recall_of_field) of a mesh (normalised frame: verts [V, 3], faces [F, 3])
    in views (poses [V, 4, 4], cameras, silhouettes bool [H, W]); with their means and minima."""
    rows = []
    for k, (pose, cam, sil) in enumerate(zip(poses, cameras, silhouettes)):
        d = mesh_depth(verts, faces, np.asarray(pose, np.float64), cam)
        row = coverage_scores(np.isfinite(d), sil)
        if field_depth is not None:
            valid = field_opacity[k] >= 0.5
            own = coverage_scores(valid, sil)  # the field's own silhouette: the most a mesh of it can cover
            row["field_iou"], row["field_recall"] = own["iou"], own["recall"]
            row["recall_of_field"] = coverage_scores(np.isfinite(d), valid)["recall"]
            row["depth_within_tol"], row["depth_pixels"] = depth_agreement(d, field_depth[k], valid, tol)
            inner = valid & interior_pixels(sil, field_depth[k], tol)
            row["depth_within_tol_interior"], row["interior_pixels"] = depth_agreement(d, field_depth[k], inner, tol)
            if field_median is not None:
                row["depth_within_tol_median"], _ = depth_agreement(d, field_median[k], valid, tol)
                inner_median = valid & interior_pixels(sil, field_median[k], tol)
                row["normals_within_deg"], row["normal_median_deg"], _ = normal_agreement(
                    verts, faces, np.asarray(pose, np.float64), cam, field_median[k], inner_median)
        rows.append(row)
    out = {"views": rows, **mesh_roughness(verts, faces)}
    for key in rows[0] if rows else ():
        if key not in ("depth_pixels", "interior_pixels"):
            vals = [r[key] for r in rows]
            out[f"{key}_mean"], out[f"{key}_min"] = float(np.mean(vals)), float(np.min(vals))
    return out


def depth_map_normals(depth: np.ndarray, c2w: np.ndarray, camera, step: int = NORMAL_STEP) -> np.ndarray:
    """Unit normals [H, W, 3] (world frame, facing the camera; 0 within `step` of the border) of the surface
    a z-depth map [H, W] shows: the cross product of central differences of its back-projected points."""
    o, d = camera_rays(c2w, camera)  # d has z-depth 1 along it
    pts = o + depth[..., None] * d
    n = np.zeros(pts.shape)
    s = step
    dx = pts[s:-s, 2 * s:] - pts[s:-s, :-2 * s]
    dy = pts[2 * s:, s:-s] - pts[:-2 * s, s:-s]
    n[s:-s, s:-s] = np.cross(dx, dy)
    n *= np.where(np.sum(n * d, -1, keepdims=True) > 0, -1.0, 1.0)  # towards the camera
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


def mesh_normals_seen(verts: np.ndarray, faces: np.ndarray, c2w: np.ndarray, camera):
    """(unit normals [H, W, 3] of the face each pixel sees, facing the camera; z-depth [H, W], inf where none)."""
    p = (np.asarray(verts, np.float64) - c2w[:3, 3]) @ np.asarray(c2w, np.float64)[:3, :3]
    u, v, front = project_points(verts, c2w, camera)
    xy = np.stack([np.where(front, u, 0.0), np.where(front, v, 0.0)], -1)
    face_id, _, depth = rasterize(xy, np.where(front, -p[:, 2], -1.0), faces, camera.height, camera.width)
    tri = np.asarray(verts, np.float64)[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=-1, keepdims=True), 1e-12)
    n = np.where((face_id >= 0)[..., None], fn[np.maximum(face_id, 0)], 0.0)
    _, d = camera_rays(c2w, camera)
    n *= np.where(np.sum(n * d, -1, keepdims=True) > 0, -1.0, 1.0)
    return n, depth


def normal_agreement(verts, faces, c2w, camera, field_median: np.ndarray, valid: np.ndarray) -> tuple[float, float, int]:
    """(share within NORMAL_DEG, median angle in degrees, pixels) of the angle between the mesh's face normals
    and the field's median-depth normals (depth_map_normals) on the pixels `valid` where the mesh shows."""
    mesh_n, depth = mesh_normals_seen(verts, faces, c2w, camera)
    field_n = depth_map_normals(field_median, c2w, camera)
    both = valid & np.isfinite(depth) & (np.linalg.norm(field_n, axis=-1) > 0.5)
    if not both.any():
        return 0.0, 180.0, 0
    ang = np.degrees(np.arccos(np.clip(np.sum(mesh_n[both] * field_n[both], -1), -1.0, 1.0)))
    return float(np.mean(ang <= NORMAL_DEG)), float(np.median(ang)), int(both.sum())


def mesh_roughness(verts: np.ndarray, faces: np.ndarray) -> dict:
    """The mesh alone: the median angle (degrees) between the normals of faces sharing an edge, and the share of
    faces in connected pieces of under SMALL_PIECE of all faces."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(verts, np.float64), np.asarray(faces), process=False)
    angles = np.degrees(mesh.face_adjacency_angles) if len(mesh.face_adjacency) else np.zeros(1)
    pieces = trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(faces)))
    sizes = np.array([len(p) for p in pieces]) if len(pieces) else np.zeros(1)
    small = sizes[sizes < SMALL_PIECE * len(faces)].sum()
    return {"dihedral_median_deg": float(np.median(angles)), "pieces": int(len(pieces)),
            "small_piece_faces": float(small / max(len(faces), 1))}
