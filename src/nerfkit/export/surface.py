"""Triangle-mesh helpers of the mesh export: normals, colours from the field, clean-up, files.

Colour of a surface point x with outward normal n: the field seen by a ray that comes in along -n
and crosses the surface, composited over the samples x_j = x + t_j n, t_j from +delta to -delta,

    c(x) = sum_j w_j c_j / sum_j w_j,   w_j = T_j (1 - exp(-sigma_j dt)),   T_j = exp(-sum_{i<j} sigma_i dt)

(c_j the field's colour at x_j seen along -n): the colour a camera looking straight at the surface
renders there, even where the mesh lies a grid cell off the density's peak. Where the short ray
gathers (almost) no opacity, the colour at x itself.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.export.carve import used_vertices
from nerfkit.export.files import write_atomic

COLOR_SAMPLES = 8


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit outward normals [V, 3]: area-weighted means of the incident faces' normals."""
    import trimesh

    return np.asarray(trimesh.Trimesh(verts, faces, process=False).vertex_normals, np.float32)


def surface_color_fn(density_fn, color_fn, delta: float, k: int = COLOR_SAMPLES):
    """A jitted (x [M, 3], n [M, 3]) -> rgb [M, 3] in [0, 1]: the composited colour c(x) of the module
    docstring over k samples from x + delta n to x - delta n."""
    t = jnp.asarray(np.linspace(delta, -delta, k), jnp.float32)
    dt = 2.0 * delta / (k - 1)

    @jax.jit
    def colors(x, n):
        pts = (x[:, None, :] + t[None, :, None] * n[:, None, :]).reshape(-1, 3)
        dirs = jnp.repeat(-n, k, axis=0)
        sigma = density_fn(pts).reshape(-1, k)
        rgb = color_fn(pts, dirs).reshape(-1, k, 3)
        alpha = 1.0 - jnp.exp(-sigma * dt)
        trans = jnp.exp(-jnp.concatenate([jnp.zeros_like(sigma[:, :1]), jnp.cumsum(sigma[:, :-1] * dt, axis=1)], 1))
        w = trans * alpha
        total = jnp.sum(w, axis=1, keepdims=True)
        mixed = jnp.sum(w[..., None] * rgb, axis=1) / jnp.maximum(total, 1e-6)
        own = color_fn(x, -n)
        return jnp.clip(jnp.where(total > 1e-3, mixed, own), 0.0, 1.0)

    return colors


def rgba8(rgb: np.ndarray) -> np.ndarray:
    """uint8 [M, 4] opaque RGBA of colours [M, 3] in [0, 1]."""
    return np.concatenate([np.clip(rgb, 0, 1) * 255 + 0.5, np.full((len(rgb), 1), 255.0)], axis=1).astype(np.uint8)


def drop_specks(verts: np.ndarray, faces: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(verts, faces, number dropped): drop the connected pieces (faces sharing edges) whose bounding
    box has a diagonal under `size` (specks: floaters of the field, noise of the fusion). A piece of a
    real surface that the extraction broke up stays, however small its share of the mesh."""
    import trimesh

    mesh = trimesh.Trimesh(verts, faces, process=False)
    labels = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(faces))
    n = labels.max() + 1 if len(labels) else 0
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    corner_labels = np.repeat(labels, 3)
    pts = verts[faces.reshape(-1)]
    np.minimum.at(lo, corner_labels, pts)
    np.maximum.at(hi, corner_labels, pts)
    speck = np.linalg.norm(hi - lo, axis=1) < size
    v, f = used_vertices(verts, faces[~speck[labels]])
    return v, f, int(speck.sum())


def rim_vertices(mesh) -> np.ndarray | None:
    """The indices of a trimesh mesh's vertices on open edges (edges of one face: an open mesh's rim, where the box
    cut it or no view saw), or None for a closed mesh. The smoothing filters hold them where they are: their
    one-sided neighbourhood would pull them along the surface."""
    import trimesh

    rim = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    return np.unique(mesh.edges_sorted[rim]) if len(rim) else None


TAUBIN_LAMBDA, TAUBIN_MU = 0.5, 0.53  # Taubin's classic pass band: k_PB = 1 / lambda - 1 / mu = 0.11


def taubin_smooth(verts: np.ndarray, faces: np.ndarray, pairs: int) -> np.ndarray:
    """float32 [V, 3]: the vertices after `pairs` rounds of Taubin's lambda|mu filter (Taubin 1995; trimesh's
    filter_taubin, whose `iterations` counts half-rounds). With L the umbrella operator, L(x)_i = mean of x_i's
    neighbours - x_i, each round is

        x <- x + lambda L(x),   then   x <- x - mu L(x)        (lambda = 0.5, mu = 0.53)

    a shrinking step and a slightly larger inflating one: a low-pass filter on the surface that removes the
    grid's staircase and the renders' ripple (a few edges long) and, unlike Laplacian smoothing alone, leaves
    the shape's size where it was. The vertices of open edges (an open mesh's rim: the box's cut, where no view
    saw) stay where they are: their one-sided neighbourhood would pull them along the surface. Faces (and so
    closedness) are unchanged."""
    import trimesh

    if pairs <= 0 or len(faces) == 0:
        return verts
    mesh = trimesh.Trimesh(np.asarray(verts, np.float64), faces, process=False)
    operator = trimesh.smoothing.laplacian_calculation(mesh, pinned_vertices=rim_vertices(mesh))
    trimesh.smoothing.filter_taubin(mesh, lamb=TAUBIN_LAMBDA, nu=TAUBIN_MU, iterations=2 * pairs,
                                    laplacian_operator=operator)
    return np.asarray(mesh.vertices, np.float32)


def simplify(verts: np.ndarray, faces: np.ndarray, max_faces: int):
    """Quadric-error decimation to at most max_faces faces (trimesh with fast-simplification)."""
    import trimesh

    if len(faces) <= max_faces:
        return verts, faces
    m = trimesh.Trimesh(verts, faces, process=False).simplify_quadric_decimation(face_count=max_faces)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int64)


def write_mesh(out: Path, verts: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> None:
    """Write a vertex-coloured mesh (.ply binary, .obj or .glb, by extension) with trimesh."""
    import trimesh

    mesh = trimesh.Trimesh(verts, faces, vertex_colors=colors, process=False)
    write_atomic(Path(out), lambda tmp: mesh.export(tmp))


def closed_and_manifold(verts: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge has exactly two faces, wound consistently (trimesh's is_watertight and
    is_winding_consistent): a closed 2-manifold that encloses a volume (for 3D printing)."""
    import trimesh

    m = trimesh.Trimesh(verts, faces, process=False)
    return bool(m.is_watertight and m.is_winding_consistent)
