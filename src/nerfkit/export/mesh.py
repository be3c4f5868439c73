"""`nerfkit export mesh`: a trained run (a field, or Gaussian splats) as a coloured triangle mesh in the capture's
coordinates.

Two ways to find the surface (`--method`):

    tsdf      (default) fuse the run's rendered median depth and opacity from about 64 training views (up to 160
              of a model that renders whole images) into a truncated signed distance on a grid over the box,
              blurred by --smooth pixels, marching cubes of its zero (tsdf.py). Every surface some view renders
              opaque is there, whatever the field's density level there; any run whose renderer gives a median
              depth (Supports.depth) meshes so.
    levelset  (a density field only) marching cubes of the density at one level, the faces the views see, moved onto the
              half-opaque surface and into the training silhouettes (levelset.py; the exports of the last
              round): exact where the field's density is high, holes where it is soft.

Then: connected pieces of the fused surface under SPECK_CELLS grid cells across are dropped (specks), the
surface is smoothed by `--taubin` rounds of Taubin's filter (surface.taubin_smooth; TAUBIN_PAIRS for tsdf, none for
the level set, whose vertices were placed on the density) and then by `--bilateral` rounds of bilateral normal
filtering, which flattens what noise is left and keeps edges (denoise.py; BILATERAL_ROUNDS for tsdf, none for the
level set), `--watertight` closes the surface (points every view
sees hidden behind a surface are inside; the box closes what it cuts) and checks it is a closed manifold,
`--max-faces` decimates, and the colour is the field's, seen straight at the surface (surface.py), or for a run
without a density field (splats) what its fused views render there (viewcolor.py): per vertex, or with `--texture`
in a UV atlas image (texture.py: a .glb, or .obj + .mtl + .png).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tyro

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.outputs import check_new_file
from nerfkit.export.carve import pixel_footprint
from nerfkit.export.denoise import bilateral_smooth
from nerfkit.export.files import check_out, to_capture
from nerfkit.export.grid import chunked, field_functions
from nerfkit.export.levelset import levelset_surface
from nerfkit.export.pictures import mesh_picture
from nerfkit.export.registry import Exporter, check_accepts
from nerfkit.export.surface import (
    closed_and_manifold,
    drop_specks,
    rgba8,
    simplify,
    surface_color_fn,
    taubin_smooth,
    vertex_normals,
    write_mesh,
)
from nerfkit.export.texture import bake, textured_files, write_textured
from nerfkit.export.tsdf import SMOOTH_PIXELS, truncation, tsdf_surface
from nerfkit.export.viewcolor import view_color_fn
from nerfkit.render.images import check_every
from nerfkit.run.folder import RunFolder

METHODS = ("tsdf", "levelset")
MESH_SUFFIXES = (".ply", ".obj", ".glb")
TEXTURE_SUFFIXES = (".glb", ".obj")
SPECK_CELLS = 4.0  # pieces smaller than this many grid cells across (bounding-box diagonal) are dropped
TEXTURE_FACES = 100_000  # --texture decimates to this many faces unless --max-faces says otherwise
COLOR_CELLS = 2.0  # the colour ray crosses the surface from this many grid cells out to as many in
# Rounds of Taubin smoothing of a tsdf surface, chosen on the procedural scene's exact surfaces
# (benchmarks/mesh_procedural.py): a splat run's normals within 10 degrees of the truth rose with the rounds (a probe
# of 0, 2, 5, 10, 20, 40: 66, 71, 73, 74, 76, 76% of the surface) while its distance to the truth stayed (0.64 to
# 0.61 cells); checked on lego's and maryrose's held-out views, where IoU and depth agreement moved by under 0.2
# points (docs/verbs/export.md, CHANGELOG).
TAUBIN_PAIRS = 20
MAX_ROUNDS = 500  # of either filter
# Rounds of bilateral normal filtering after Taubin's: on the procedural scene's exact surfaces a splat run's normals
# within 10 degrees of the truth went from 76% of the surface to 81% at 10 rounds and 85% at 40 (the exact depth
# maps' mesh 87.3 -> 91.5 / 92.5%), its distance to the truth unchanged; on lego's held-out views (the tuning half)
# 40 rounds took the depth agreement under 95% (0.955 -> 0.949) and the normals' agreement with the run's depth down
# 5 points, where 10 moved the first by a tenth of a point and the second by one (maryrose: neither).
# docs/verbs/export.md, CHANGELOG.
BILATERAL_ROUNDS = 10


def check_options(resolution: int, method: str, box: float | None, max_faces: int | None, texture_size: int,
                  threshold: float | None, taubin: int | None = None, bilateral: int | None = None) -> None:
    """One line per bad value, before any work."""
    if method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)} (got {method!r})")
    if not 16 <= resolution <= 1024:
        raise ConfigError(f"--resolution must be between 16 and 1024 grid points per axis (got {resolution})")
    if threshold is not None and not threshold > 0:
        raise ConfigError(f"--threshold must be a positive density (got {threshold})")
    if max_faces is not None and max_faces < 4:
        raise ConfigError(f"--max-faces must be at least 4 (got {max_faces})")
    if box is not None and not 1e-3 <= box <= 1e3:
        raise ConfigError(f"--box must be a half-size between 0.001 and 1000 of the run's normalised units (got {box})")
    if not 64 <= texture_size <= 8192:
        raise ConfigError(f"--texture-size must be between 64 and 8192 texels (got {texture_size})")
    if taubin is not None and not 0 <= taubin <= MAX_ROUNDS:
        raise ConfigError(f"--taubin must be between 0 and {MAX_ROUNDS} rounds of smoothing (got {taubin})")
    if bilateral is not None and not 0 <= bilateral <= MAX_ROUNDS:
        raise ConfigError(f"--bilateral must be between 0 and {MAX_ROUNDS} rounds of filtering (got {bilateral})")


def default_out(run_dir: Path, texture: bool) -> Path:
    return Path(run_dir) / "exports" / ("mesh.glb" if texture else "mesh.ply")


def export_mesh(run_dir: Path, out: Path | None = None, resolution: int = 256, threshold: float | None = None,
                max_faces: int | None = None, visible_only: bool = True, snap: bool = True, every: int | None = None,
                data: Path | None = None, progress: bool = True, log=print, carve: bool = True,
                overwrite: bool = False, method: str = "tsdf", box: float | None = None, watertight: bool = False,
                texture: bool = False, texture_size: int = 1024, smooth: float = SMOOTH_PIXELS,
                taubin: int | None = None, bilateral: int | None = None) -> dict:
    """Write the run's mesh to `out` (default RUN/exports/mesh.ply, or mesh.glb with `texture`) in the
    capture's coordinates, with a record and a picture in RUN/exports/; returns the record.

    method: "tsdf" or "levelset" (module docstring); threshold, visible_only, snap and carve belong to
    the level set (levelset.levelset_surface). box: half-size of the exported box in normalised units
    (default: the field's box, or the inner ball of an unbounded scene). watertight: a closed manifold
    (tsdf only). texture: a UV atlas of texture_size^2 texels instead of vertex colours. smooth: the blur of the
    fused distance, in pixel footprints (tsdf only; tsdf.smooth_volume). taubin: rounds of Taubin smoothing of the
    surface (surface.taubin_smooth; None: TAUBIN_PAIRS for tsdf, 0 for the level set). bilateral: rounds of
    bilateral normal filtering after it (denoise.bilateral_smooth; None: BILATERAL_ROUNDS for tsdf, 0 for the level
    set)."""
    if not 0 <= smooth <= 8:
        raise ConfigError(f"--smooth must be between 0 and 8 pixel footprints (got {smooth})")
    check_every(every)
    out = checked_out(run_dir, out, resolution, method, box, max_faces, texture, texture_size, threshold, watertight,
                      overwrite, taubin, bilateral)
    taubin = (TAUBIN_PAIRS if method == "tsdf" else 0) if taubin is None else taubin
    bilateral = (BILATERAL_ROUNDS if method == "tsdf" else 0) if bilateral is None else bilateral
    t0 = time.perf_counter()
    run = RunFolder(run_dir).load()
    check_accepts(EXPORTER, run_dir, run.model.supports, run.model.title)
    bound = run.bound if box is None else float(box)
    h = 2.0 * bound / (resolution - 1)
    if method == "levelset" and not run.model.supports.mesh:
        raise ConfigError(f"--method levelset marches a density field; a {run.model.title} run has none: use "
                          f"--method tsdf (the default), which fuses its rendered depth")
    views = None
    if method == "tsdf":
        verts, faces, info, views = tsdf_surface(run, bound, resolution, every, data, watertight, progress, log,
                                                 smooth)
    else:
        verts, faces, info = levelset_surface(run, bound, resolution, threshold, visible_only, snap, every, data,
                                              carve, progress, log)
    verts, faces, cleaned = clean_up(verts, faces, method, h, max_faces, texture, watertight, log, (taubin, bilateral),
                                     bound)
    record = {"kind": "mesh", "file": str(out.resolve()), "method": method, "step": run.step,
              "resolution": resolution, "bound": bound, "box_rule": "--box" if box is not None else "the field's box",
              "watertight_requested": watertight, **cleaned, **info}
    colors = write_coloured(run, out, verts, faces, h, texture, texture_size, record, log, views)
    picture = mesh_picture(run.run_dir / "exports" / "mesh.png", verts, faces, colors,
                           f"{out.name}: {len(verts)} vertices, {len(faces)} faces ({method}, step {run.step})")
    record.update({"vertices": len(verts), "faces": len(faces), "seconds": round(time.perf_counter() - t0, 2),
                   "picture": picture.name, "coordinates": "the capture's own (pose normalisation undone)"})
    RunFolder(run.run_dir).write_record("mesh", record)
    return record


def checked_out(run_dir, out, resolution, method, box, max_faces, texture, texture_size, threshold, watertight,
                overwrite, taubin: int | None = None, bilateral: int | None = None) -> Path:
    """The file to write (every option checked, in one line each, before any work; nothing overwritten
    without `overwrite`)."""
    check_options(resolution, method, box, max_faces, texture_size, threshold, taubin, bilateral)
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


def clean_up(verts, faces, method: str, h: float, max_faces: int | None, texture: bool, watertight: bool, log,
             smoothing: tuple[int, int] = (0, 0), bound: float = np.inf):
    """(verts, faces, record fields): specks of the fused surface dropped (the level set keeps its pieces, as
    in the exports of the last round), smoothed by `smoothing` = (taubin, bilateral) rounds of Taubin's filter and
    then of bilateral normal filtering (kept in the box [-bound, bound]^3: the inflating step moves a closed mesh's
    corners on the box a little out), decimated to max_faces (TEXTURE_FACES with a texture), and checked to be a
    closed manifold (an error when `watertight` asked for one)."""
    n_surface, dropped = len(faces), 0
    if method == "tsdf":
        verts, faces, dropped = drop_specks(verts, faces, SPECK_CELLS * h)
        log(f"mesh: {len(faces)} faces; {dropped} specks under {SPECK_CELLS:g} grid cells across dropped "
            f"({n_surface - len(faces)} faces)")
    taubin, bilateral = smoothing
    if taubin:
        verts = np.clip(taubin_smooth(verts, faces, taubin), -bound, bound)
        log(f"mesh: smoothed by {taubin} rounds of Taubin's filter")
    if bilateral:
        verts = np.clip(bilateral_smooth(verts, faces, bilateral), -bound, bound)
        log(f"mesh: {bilateral} rounds of bilateral normal filtering")
    n_faces = len(faces)
    limit = max_faces if max_faces is not None else (TEXTURE_FACES if texture else None)
    if limit is not None:
        verts, faces = simplify(verts, faces, limit)
    closed = closed_and_manifold(verts, faces)
    if watertight and not closed:
        raise NerfkitError("the closed surface came out with open or non-manifold edges after clean-up; try "
                           "without --max-faces or at another --resolution")
    return verts, faces, {"faces_of_surface": n_surface, "pieces_dropped": dropped, "taubin_pairs": taubin,
                          "bilateral_rounds": bilateral,
                          "faces_before_simplification": n_faces, "closed_manifold": closed}


def colour_function(run, h: float, views):
    """(x [M, 3], n [M, 3]) -> rgb [M, 3]: the field seen straight at the surface (surface.py) where the model has
    a density field, else the rendered views' colour there (viewcolor.py; views: the fused ones)."""
    if run.model.supports.mesh:
        density_fn, color_fn, _, _ = field_functions(run)
        return surface_color_fn(density_fn, color_fn, COLOR_CELLS * h)
    tol = truncation(h, pixel_footprint(views.c2w, views.cameras))  # the fusion's: a few grid cells
    return view_color_fn(views.c2w, views.intrinsics, views.rgb, views.opacity, views.median,
                         np.asarray(run.model.background, np.float32), tol)


def write_coloured(run, out: Path, verts, faces, h: float, texture: bool, texture_size: int, record: dict,
                   log, views=None) -> np.ndarray:
    """Colour the mesh (colour_function) and write it in the capture's coordinates: vertex colours, or with
    `texture` a UV atlas (texture.py; its files go into the record). Returns the vertex colours (uint8 [V, 4],
    for the picture)."""
    colors_of = colour_function(run, h, views)
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


@dataclass
class ExportMeshArgs:
    """Export the run's surface as a coloured triangle mesh, in the capture's own coordinates; a picture from two
    sides goes into RUN_DIR/exports/mesh.png. The default fuses the run's rendered depth from about 64
    training views (up to 160 of a splat run; TSDF) and closes nothing it did not see; --watertight closes it,
    --texture bakes a UV texture."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    out: Path | None = None
    """Mesh file: .ply, .obj or .glb (default: RUN_DIR/exports/mesh.ply; with --texture .glb or .obj, default
    RUN_DIR/exports/mesh.glb)."""
    method: str = "tsdf"
    """tsdf: fuse rendered depth into a signed distance (whole surfaces, closable); levelset: marching cubes of the
    density at one level (the last round's export; holes where the field is soft)."""
    resolution: int = 256
    """Grid points per axis of the box."""
    box: float | None = None
    """Half-size of the exported box in the run's normalised units (default: the field's box; for an unbounded
    scene its inner ball, where the cameras look)."""
    watertight: bool = False
    """tsdf: a closed manifold mesh (for 3D printing): what no view saw behind a surface is filled, the box closes
    what it cuts."""
    texture: bool = False
    """Bake the colour into a UV texture (xatlas atlas; .glb with the image inside, or .obj + .mtl + .png),
    decimated to 100,000 faces unless --max-faces says otherwise."""
    texture_size: int = 1024
    """Texels per side of the texture atlas, roughly: xatlas scales the charts to it, and the padding between
    many small charts can make the atlas up to about twice as wide (the record gives the size)."""
    smooth: float = SMOOTH_PIXELS
    """tsdf: blur the fused distance by a Gaussian of this many pixel footprints before the surface is taken (0:
    none). Each view's depth is read once per pixel, which leaves ripples of a pixel's size on the surface; half a
    pixel removes them; more smooths away the run's own noise, and fine detail with it."""
    taubin: int | None = None
    """Smooth the mesh by this many rounds of Taubin's filter (a shrinking and an inflating step each: removes
    ripples a few edges long and keeps the shape's size; 0: none). Default: 20 for tsdf, 0 for the level set."""
    bilateral: int | None = None
    """Then this many rounds of bilateral normal filtering (each face's normal averaged with its neighbours' where
    they point the same way, the vertices moved onto the filtered faces: flattens the noise left on flat and gently
    curved parts and keeps edges sharp; 0: none). Default: 10 for tsdf, 0 for the level set."""
    max_faces: int | None = None
    """Simplify the mesh to at most this many faces (quadric decimation)."""
    every: int | None = None
    """Render every K-th training view (default: about 64 views for tsdf, 160 for a splat run, 32 for the
    levelset's visibility)."""
    threshold: float | None = None
    """levelset: density level of the surface (default: ln 2 / grid spacing, where one grid cell is half opaque)."""
    visible_only: bool = True
    """levelset: keep only faces some training view sees (drops the arbitrary surfaces inside objects and under
    them)."""
    snap: bool = True
    """levelset: move each vertex along its normal (within one grid cell) to where a ray from outside turns half
    opaque."""
    carve: bool = True
    """levelset: where the capture has masks or an alpha channel, move vertices that fall outside the training
    silhouettes into them (up to two grid cells or two pixels); drop faces the photos show background through."""
    data: Path | None = None
    """The data folder (for the training cameras); default: the one the run was trained on."""
    progress: bool = True
    """Show progress bars."""
    overwrite: bool = False
    """Replace --out if it exists."""

MESH_LEVELSET_FLAGS = ("--threshold", "--visible-only", "--no-visible-only", "--snap", "--no-snap", "--carve",
                       "--no-carve")


def _export(a: ExportMeshArgs, given: set[str]) -> dict:
    """export_mesh with the flags a user typed checked against each other (`given`: the flags typed)."""
    if a.method != "levelset":
        moot = [f for f in MESH_LEVELSET_FLAGS if f in given]
        if moot:
            raise ConfigError(f"{moot[0]} belongs to --method levelset (this export uses --method {a.method}); "
                              f"drop it or pass --method levelset")
    if a.method == "levelset" and "--smooth" in given:
        raise ConfigError("--smooth blurs the fused distance of --method tsdf; drop it or use --method tsdf")
    if a.method == "levelset" and not a.visible_only and "--every" in given:
        raise ConfigError("--every thins the training views of the visibility pass, which --no-visible-only "
                          "turns off; drop one of them")
    if not a.texture and "--texture-size" in given:
        raise ConfigError("--texture-size sets the texture of --texture; pass --texture too, or drop it")
    return export_mesh(a.run_dir, a.out, a.resolution, a.threshold, a.max_faces, a.visible_only, a.snap, a.every,
                       a.data, progress=a.progress, carve=a.carve, overwrite=a.overwrite, method=a.method, box=a.box,
                       watertight=a.watertight, texture=a.texture, texture_size=a.texture_size, smooth=a.smooth,
                       taubin=a.taubin, bilateral=a.bilateral)


def _wrote(rec: dict) -> str:
    closed = "closed manifold" if rec["closed_manifold"] else "open where no view saw the surface"
    files = rec["texture"]["files"] if "texture" in rec else [rec["file"]]
    return (f"wrote {', '.join(files)}: {rec['vertices']} vertices, {rec['faces']} faces, {closed} "
            f"({rec['method']}, {rec['seconds']:.1f} s)")


def _facts(rec: dict) -> str:
    if rec.get("method", "levelset") == "levelset":
        return "{vertices} vertices, {faces} faces, threshold {threshold:.4g}".format(**rec)
    closed = ", closed" if rec.get("closed_manifold") else ""
    return "{vertices} vertices, {faces} faces, {method} of {views} views".format(**rec) + closed


EXPORTER = Exporter(
    name="mesh", summary="a coloured triangle mesh (.ply, .obj, .glb; TSDF or level set, optionally textured)",
    args=ExportMeshArgs, accepts=lambda supports: supports.mesh or supports.depth,
    needs="a density field or rendered depth to mesh",
    outputs=("mesh.ply", "mesh.png"), export=_export, wrote=_wrote, facts=_facts)
