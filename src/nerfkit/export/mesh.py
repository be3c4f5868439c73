"""`nerfkit export mesh`: a trained field as a coloured triangle mesh in the capture's coordinates.

Two ways to find the surface (`--method`):

    tsdf      (default) fuse the field's rendered depth and opacity from about 64 training views into a
              truncated signed distance on a grid over the box, marching cubes of its zero (tsdf.py). Every
              surface some view renders opaque is there, whatever the field's density level there.
    levelset  marching cubes of the density at one level, the faces the views see, moved onto the
              half-opaque surface and into the training silhouettes (levelset.py; the exports of the last
              round): exact where the field's density is high, holes where it is soft.

Then: connected pieces of the fused surface under SPECK_CELLS grid cells across are dropped (specks),
`--watertight` closes the surface (points every view sees hidden behind a surface are inside; the box
closes what it cuts) and checks it is a closed manifold, `--max-faces` decimates, and the colour is the
field's, seen straight at the surface (surface.py): per vertex, or with `--texture` in a UV atlas image
(texture.py: a .glb, or .obj + .mtl + .png).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.outputs import check_new_file
from nerfkit.export.files import check_out, to_capture
from nerfkit.export.grid import chunked, field_functions
from nerfkit.export.levelset import levelset_surface
from nerfkit.export.pictures import mesh_picture
from nerfkit.export.surface import (
    closed_and_manifold,
    drop_specks,
    rgba8,
    simplify,
    surface_color_fn,
    vertex_normals,
    write_mesh,
)
from nerfkit.export.texture import bake, textured_files, write_textured
from nerfkit.export.tsdf import tsdf_surface
from nerfkit.run.folder import RunFolder

METHODS = ("tsdf", "levelset")
MESH_SUFFIXES = (".ply", ".obj", ".glb")
TEXTURE_SUFFIXES = (".glb", ".obj")
SPECK_CELLS = 4.0  # pieces smaller than this many grid cells across (bounding-box diagonal) are dropped
TEXTURE_FACES = 100_000  # --texture decimates to this many faces unless --max-faces says otherwise
COLOR_CELLS = 2.0  # the colour ray crosses the surface from this many grid cells out to as many in


def check_options(resolution: int, method: str, box: float | None, max_faces: int | None, texture_size: int,
                  threshold: float | None) -> None:
    """One line per bad value, before any work."""
    if method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)} (got {method!r})")
    if not 16 <= resolution <= 1024:
        raise ConfigError(f"--resolution must be between 16 and 1024 grid points per axis (got {resolution})")
    if threshold is not None and not threshold > 0:
        raise ConfigError(f"--threshold must be a positive density (got {threshold})")
    if max_faces is not None and max_faces < 4:
        raise ConfigError(f"--max-faces must be at least 4 (got {max_faces})")
    if box is not None and not box > 0:
        raise ConfigError(f"--box must be a positive half-size in the run's normalised units (got {box})")
    if not 64 <= texture_size <= 8192:
        raise ConfigError(f"--texture-size must be between 64 and 8192 texels (got {texture_size})")


def default_out(run_dir: Path, texture: bool) -> Path:
    return Path(run_dir) / "exports" / ("mesh.glb" if texture else "mesh.ply")


def export_mesh(run_dir: Path, out: Path | None = None, resolution: int = 256, threshold: float | None = None,
                max_faces: int | None = None, visible_only: bool = True, snap: bool = True, every: int | None = None,
                data: Path | None = None, progress: bool = True, log=print, carve: bool = True,
                overwrite: bool = False, method: str = "tsdf", box: float | None = None, watertight: bool = False,
                texture: bool = False, texture_size: int = 1024) -> dict:
    """Write the run's mesh to `out` (default RUN/exports/mesh.ply, or mesh.glb with `texture`) in the
    capture's coordinates, with a record and a picture in RUN/exports/; returns the record.

    method: "tsdf" or "levelset" (module docstring); threshold, visible_only, snap and carve belong to
    the level set (levelset.levelset_surface). box: half-size of the exported box in normalised units
    (default: the field's box, or the inner ball of an unbounded scene). watertight: a closed manifold
    (tsdf only). texture: a UV atlas of texture_size^2 texels instead of vertex colours."""
    out = checked_out(run_dir, out, resolution, method, box, max_faces, texture, texture_size, threshold, watertight,
                      overwrite)
    t0 = time.perf_counter()
    run = RunFolder(run_dir).load()
    if run.cfg.field.kind == "splat":
        raise ConfigError(f"{run_dir}: Gaussian splats have no density field to mesh; export them with nerfkit "
                          f"export splat (or export pointcloud for points)")
    bound = run.bound if box is None else float(box)
    h = 2.0 * bound / (resolution - 1)
    if method == "tsdf":
        verts, faces, info = tsdf_surface(run, bound, resolution, every, data, watertight, progress, log)
    else:
        verts, faces, info = levelset_surface(run, bound, resolution, threshold, visible_only, snap, every, data,
                                              carve, progress, log)
    verts, faces, cleaned = clean_up(verts, faces, method, h, max_faces, texture, watertight, log)
    record = {"kind": "mesh", "file": str(out.resolve()), "method": method, "step": run.step,
              "resolution": resolution, "bound": bound, "box_rule": "--box" if box is not None else "the field's box",
              "watertight_requested": watertight, **cleaned, **info}
    colors = write_coloured(run, out, verts, faces, h, texture, texture_size, record, log)
    picture = mesh_picture(run.run_dir / "exports" / "mesh.png", verts, faces, colors,
                           f"{out.name}: {len(verts)} vertices, {len(faces)} faces ({method}, step {run.step})")
    record.update({"vertices": len(verts), "faces": len(faces), "seconds": round(time.perf_counter() - t0, 2),
                   "picture": picture.name, "coordinates": "the capture's own (pose normalisation undone)"})
    RunFolder(run.run_dir).write_record("mesh", record)
    return record


def checked_out(run_dir, out, resolution, method, box, max_faces, texture, texture_size, threshold, watertight,
                overwrite) -> Path:
    """The file to write (every option checked, in one line each, before any work; nothing overwritten
    without `overwrite`)."""
    check_options(resolution, method, box, max_faces, texture_size, threshold)
    if method == "tsdf" and threshold is not None:
        raise ConfigError("--threshold is the density level of --method levelset; the tsdf surface is where "
                          "the rendered depth puts it")
    if method == "levelset" and watertight:
        raise ConfigError("--watertight closes the fused surface of --method tsdf; the level set drops unseen "
                          "faces, so it is open: use --method tsdf --watertight")
    out = Path(out) if out is not None else default_out(run_dir, texture)
    if texture and out.suffix.lower() == ".ply":
        raise ConfigError(f"--out {out}: a textured mesh is written as .glb (texture inside) or .obj (+ .mtl + .png)")
    out = check_out(out, TEXTURE_SUFFIXES if texture else MESH_SUFFIXES, overwrite)
    if texture and out.suffix.lower() == ".obj":
        for side in textured_files(out)[1:]:
            check_new_file(side, overwrite, "--out")
    return out


def clean_up(verts, faces, method: str, h: float, max_faces: int | None, texture: bool, watertight: bool, log):
    """(verts, faces, record fields): specks of the fused surface dropped (the level set keeps its pieces, as
    in the exports of the last round), decimated to max_faces (TEXTURE_FACES with a texture), and checked to
    be a closed manifold (an error when `watertight` asked for one)."""
    n_surface, dropped = len(faces), 0
    if method == "tsdf":
        verts, faces, dropped = drop_specks(verts, faces, SPECK_CELLS * h)
        log(f"mesh: {len(faces)} faces; {dropped} specks under {SPECK_CELLS:g} grid cells across dropped "
            f"({n_surface - len(faces)} faces)")
    n_faces = len(faces)
    limit = max_faces if max_faces is not None else (TEXTURE_FACES if texture else None)
    if limit is not None:
        verts, faces = simplify(verts, faces, limit)
    closed = closed_and_manifold(verts, faces)
    if watertight and not closed:
        raise NerfkitError("the closed surface came out with open or non-manifold edges after clean-up; try "
                           "without --max-faces or at another --resolution")
    return verts, faces, {"faces_of_surface": n_surface, "pieces_dropped": dropped,
                          "faces_before_simplification": n_faces, "closed_manifold": closed}


def write_coloured(run, out: Path, verts, faces, h: float, texture: bool, texture_size: int, record: dict,
                   log) -> np.ndarray:
    """Colour the mesh with the field seen straight at its surface (surface.py) and write it in the capture's
    coordinates: vertex colours, or with `texture` a UV atlas (texture.py; its files go into the record).
    Returns the vertex colours (uint8 [V, 4], for the picture)."""
    density_fn, color_fn, _, _ = field_functions(run)
    colors_of = surface_color_fn(density_fn, color_fn, COLOR_CELLS * h)
    normals = vertex_normals(verts, faces)
    colors = rgba8(chunked(colors_of, verts.astype(np.float32), normals, chunk=16384))
    if texture:
        log(f"mesh: texture atlas (xatlas, about {texture_size}^2 texels) for {len(faces)} faces...")
        uv, tex_faces, tex_verts, image = bake(verts, normals, faces, texture_size,
                                               lambda p, n: chunked(colors_of, p, n, chunk=16384))
        files = write_textured(out, to_capture(tex_verts, run.transform), tex_faces, uv, image)
        record["texture"] = {"files": [str(f.resolve()) for f in files], "size": list(image.shape[1::-1])}
    else:
        write_mesh(out, to_capture(verts, run.transform), faces, colors)
    return colors
