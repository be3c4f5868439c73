"""Scan conversion of triangles into a pixel grid with a depth test (numba): for texture baking
(triangles laid out in UV space) and for measuring a mesh against photos (triangles projected
into a camera).

Pixel (i, j) (row i, column j) covers [j, j + 1) x [i, i + 1) and is sampled at its centre
(j + 1/2, i + 1/2). For a triangle with 2D corners p_a, p_b, p_c, the centre q is inside when its
barycentric coordinates

    l_a = E(p_b, p_c, q) / E(p_a, p_b, p_c),  l_b = E(p_c, p_a, q) / E,  l_c = 1 - l_a - l_b,
    E(p, r, q) = (r - p) x (q - p)   (the signed doubled area)

are all >= 0 (either winding). Its depth is interpolated perspective-correctly, 1/z = sum_i l_i / z_i
(screen-space barycentrics are linear in 1/z); the nearest triangle wins.
"""

from __future__ import annotations

import numba
import numpy as np

from nerfkit.rays.cameras import project_points


@numba.njit(cache=True)
def _scan(xy, z, faces, height, width, face_id, bary, depth):
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, bx, by, cx, cy = xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], xy[c, 0], xy[c, 1]
        za, zb, zc = z[a], z[b], z[c]
        if za <= 0.0 or zb <= 0.0 or zc <= 0.0:
            continue
        area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if area == 0.0 or not np.isfinite(area):
            continue
        j0 = max(int(np.floor(min(ax, bx, cx) - 0.5)), 0)
        j1 = min(int(np.ceil(max(ax, bx, cx) - 0.5)), width - 1)
        i0 = max(int(np.floor(min(ay, by, cy) - 0.5)), 0)
        i1 = min(int(np.ceil(max(ay, by, cy) - 0.5)), height - 1)
        for i in range(i0, i1 + 1):
            qy = i + 0.5
            for j in range(j0, j1 + 1):
                qx = j + 0.5
                la = ((cx - bx) * (qy - by) - (qx - bx) * (cy - by)) / area
                lb = ((ax - cx) * (qy - cy) - (qx - cx) * (ay - cy)) / area
                lc = 1.0 - la - lb
                if la < 0.0 or lb < 0.0 or lc < 0.0:
                    continue
                zq = 1.0 / (la / za + lb / zb + lc / zc)
                if zq < depth[i, j]:
                    depth[i, j] = zq
                    face_id[i, j] = f
                    bary[i, j, 0] = la
                    bary[i, j, 1] = lb
                    bary[i, j, 2] = lc


def rasterize(xy: np.ndarray, z: np.ndarray, faces: np.ndarray, height: int, width: int):
    """Scan-convert triangles: xy [V, 2] pixel coordinates (x right, y down) and depths z [V] (> 0;
    triangles with a corner at z <= 0 are skipped) of the vertices, faces int [F, 3].

    Returns face_id int32 [H, W] (-1: no triangle), bary float32 [H, W, 3] (screen-space barycentric
    coordinates of the pixel centre in its triangle) and depth float32 [H, W] (inf where empty)."""
    face_id = np.full((height, width), -1, np.int32)
    bary = np.zeros((height, width, 3), np.float32)
    depth = np.full((height, width), np.inf, np.float32)
    _scan(np.ascontiguousarray(xy, np.float64), np.ascontiguousarray(z, np.float64),
          np.ascontiguousarray(faces, np.int64), height, width, face_id, bary, depth)
    return face_id, bary, depth


def mesh_depth(verts: np.ndarray, faces: np.ndarray, c2w: np.ndarray, camera) -> np.ndarray:
    """float32 [H, W]: the z-depth of the mesh (world vertices [V, 3]) seen by a camera at c2w
    (OpenGL axes; its lens included, vertex by vertex), inf where it shows no triangle."""
    p = (np.asarray(verts, np.float64) - c2w[:3, 3]) @ np.asarray(c2w, np.float64)[:3, :3]
    z = -p[:, 2]
    u, v, front = project_points(verts, c2w, camera)
    xy = np.stack([np.where(front, u, 0.0), np.where(front, v, 0.0)], -1)
    return rasterize(xy, np.where(front, z, -1.0), faces, camera.height, camera.width)[2]
