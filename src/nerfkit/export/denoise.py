"""Feature-preserving smoothing of a mesh: bilateral filtering of its face normals, then its vertices moved onto
the filtered faces' planes (Zheng et al. 2011, "Bilateral normal filtering for mesh denoising"; the vertex update of
Sun et al. 2007).

A face i has centroid c_i, unit normal n_i and area A_i; its neighbours j are the faces that share a vertex with it
(i itself included). One round of the normal filter is

    n_i <- normalize( sum_j A_j W_s(|c_i - c_j|) W_r(|n_i - n_j|) n_j ),
    W_s(d) = exp(-d^2 / (2 sigma_s^2)),   W_r(d) = exp(-d^2 / (2 sigma_r^2)),

with sigma_s the mean distance between neighbouring centroids (the mesh's own scale) and sigma_r a distance
between unit normals (0.2: about 11 degrees). A neighbour across a crease (a box edge: |n_i - n_j| = 1.4) weighs
exp(-25) of one on the same plane, so the filter flattens noise on each side of an edge and keeps the edge, where
Taubin's and Laplacian smoothing round it. The vertices then follow the filtered normals: one round of

    x_k <- x_k + 1/|F_k| sum_{j in F_k} n_j (n_j . (c_j - x_k))        (F_k: the faces around vertex k)

moves each vertex towards the planes of its faces, the centroids c_j recomputed after each round. The faces, and so
a mesh's closedness, are unchanged; the vertices of open edges (an open mesh's rim) stay where they are.
"""

from __future__ import annotations

import numpy as np

from nerfkit.export.surface import rim_vertices

SIGMA_NORMAL = 0.2  # sigma_r: the distance between unit normals the range weight falls off over (about 11 degrees)


def incidence(faces: np.ndarray, n_verts: int):
    """Sparse [F, V] float64: 1 where face f has vertex v."""
    import scipy.sparse as sp

    n = len(faces)
    return sp.csr_matrix((np.ones(3 * n), (np.repeat(np.arange(n), 3), faces.reshape(-1))), shape=(n, n_verts))


def face_geometry(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centroids [F, 3], unit normals [F, 3] (zero for a degenerate face), areas [F]) of a triangle mesh."""
    p = verts[faces]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    twice_area = np.linalg.norm(cross, axis=1)
    return p.mean(axis=1), cross / np.maximum(twice_area, 1e-30)[:, None], 0.5 * twice_area


def filter_normals(centroids: np.ndarray, normals: np.ndarray, areas: np.ndarray, pattern, rounds: int,
                   sigma_r: float = SIGMA_NORMAL) -> np.ndarray:
    """Unit normals [F, 3] after `rounds` rounds of the bilateral filter of the module docstring. pattern: sparse
    [F, F] whose non-zeros are the neighbour pairs (i, j) (faces sharing a vertex, i == j included)."""
    import scipy.sparse as sp

    pattern = pattern.tocsr()
    rows = np.repeat(np.arange(pattern.shape[0]), np.diff(pattern.indptr))
    cols = pattern.indices
    d2 = np.sum((centroids[rows] - centroids[cols]) ** 2, axis=1)
    apart = rows != cols
    sigma_s = float(np.sqrt(d2[apart]).mean()) if apart.any() else 1.0
    spatial = areas[cols] * np.exp(-d2 / (2.0 * sigma_s**2))
    n = normals
    for _ in range(rounds):
        w = spatial * np.exp(-np.sum((n[rows] - n[cols]) ** 2, axis=1) / (2.0 * sigma_r**2))
        acc = sp.csr_matrix((w, cols, pattern.indptr), shape=pattern.shape) @ n
        n = acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-30)
    return n


def fit_to_normals(verts: np.ndarray, faces: np.ndarray, normals: np.ndarray, rounds: int, inc,
                   pinned: np.ndarray | None = None) -> np.ndarray:
    """float64 [V, 3]: the vertices after `rounds` rounds of the module docstring's vertex update towards the faces'
    planes (normals [F, 3] fixed, centroids recomputed each round). inc: the [F, V] incidence; pinned: vertex
    indices that stay. With N_k = sum_{j in F_k} n_j n_j^T and b_k = sum_j n_j (n_j . c_j), a round is
    x_k <- x_k + (b_k - N_k x_k) / |F_k|."""
    x = np.asarray(verts, np.float64).copy()
    to_verts = inc.T.tocsr()
    count = np.maximum(np.asarray(to_verts.sum(axis=1)), 1.0)
    outer = (to_verts @ (normals[:, :, None] * normals[:, None, :]).reshape(-1, 9)).reshape(-1, 3, 3)
    for _ in range(rounds):
        centroids = x[faces].mean(axis=1)
        b = to_verts @ (normals * np.sum(normals * centroids, axis=1, keepdims=True))
        step = (b - np.einsum("kab,kb->ka", outer, x)) / count
        if pinned is not None:
            step[pinned] = 0.0
        x += step
    return x


def bilateral_smooth(verts: np.ndarray, faces: np.ndarray, rounds: int, sigma_r: float = SIGMA_NORMAL) -> np.ndarray:
    """float32 [V, 3]: the vertices after `rounds` rounds of bilateral normal filtering and then `rounds` rounds of
    fitting the vertices to the filtered normals (module docstring); the rim of an open mesh pinned."""
    import trimesh

    if rounds <= 0 or len(faces) == 0:
        return verts
    x = np.asarray(verts, np.float64)
    pinned = rim_vertices(trimesh.Trimesh(x, faces, process=False))
    inc = incidence(faces, len(x))
    centroids, normals, areas = face_geometry(x, faces)
    filtered = filter_normals(centroids, normals, areas, inc @ inc.T, rounds, sigma_r)
    return fit_to_normals(x, faces, filtered, rounds, inc, pinned).astype(np.float32)
