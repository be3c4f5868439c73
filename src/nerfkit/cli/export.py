"""`nerfkit export mesh|pointcloud|cameras|splat`: one kind per call, each its own flags (the Export*Args
below, parsed by tyro like the other verbs' arguments in args.py)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import tyro

from nerfkit.cli.parsing import flag_value, parse
from nerfkit.core.errors import ConfigError


@dataclasses.dataclass
class ExportMeshArgs:
    """Export the run's surface as a coloured triangle mesh, in the capture's own coordinates; a picture from two
    sides goes into RUN_DIR/exports/mesh.png. The default fuses the field's rendered depth from about 64
    training views (TSDF) and closes nothing it did not see; --watertight closes it, --texture bakes a UV
    texture."""

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
    max_faces: int | None = None
    """Simplify the mesh to at most this many faces (quadric decimation)."""
    every: int | None = None
    """Render every K-th training view (default: about 64 views for tsdf, 32 for the levelset's visibility)."""
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


@dataclasses.dataclass
class ExportPointcloudArgs:
    """Export a coloured point cloud (PLY): the rendered depth of every K-th view of a split, back-projected,
    fused and voxel-downsampled, in the capture's own coordinates."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    out: Path | None = None
    """PLY file (default: RUN_DIR/exports/pointcloud.ply)."""
    split: str | None = None
    """Views to render (default: the run's training split)."""
    every: int | None = None
    """Use every K-th view (default: about 32 views, evenly spaced)."""
    min_opacity: float = 0.9
    """Keep pixels at least this opaque."""
    voxel_size: float | None = None
    """Fuse points into voxels of this size, in the capture's units (default: the box side / 512; 0: keep all)."""
    data: Path | None = None
    """The data folder; default: the one the run was trained on."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""
    progress: bool = True
    """Show progress bars."""
    overwrite: bool = False
    """Replace --out if it exists."""


@dataclasses.dataclass
class ExportSplatArgs:
    """Export a splat run's Gaussians as a .ply in the Inria 3DGS layout (what SuperSplat, gsplat, nerfstudio and
    other splat viewers open), in the capture's own coordinates; a picture of the file read back goes into
    RUN_DIR/exports/splat.png."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train --preset splat`."""
    out: Path | None = None
    """PLY file (default: RUN_DIR/exports/splat.ply)."""
    overwrite: bool = False
    """Replace --out if it exists."""


@dataclasses.dataclass
class ExportCamerasArgs:
    """Export the run's cameras as nerfstudio's transforms.json (OpenGL camera-to-world in the capture's own
    coordinates, intrinsics and lens at the photos' size, image paths relative to the written file)."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    out: Path | None = None
    """JSON file (default: RUN_DIR/exports/cameras.json)."""
    split: str | None = None
    """Export only these frames, e.g. 'test' (default: every frame, each listed under its split in the run)."""
    data: Path | None = None
    """The data folder; default: the one the run was trained on."""
    overwrite: bool = False
    """Replace --out if it exists."""


EXPORT_KINDS = ("mesh", "pointcloud", "cameras", "splat")
MESH_LEVELSET_FLAGS = ("--threshold", "--no-visible-only", "--visible-only", "--no-snap", "--snap", "--no-carve", "--carve")


def cmd_export(argv: list[str]) -> int:
    if not argv or argv[0] not in EXPORT_KINDS:
        if argv and argv[0] in ("-h", "--help"):
            print("usage: nerfkit export {mesh,pointcloud,cameras,splat} RUN_DIR [--out FILE] ...  "
                  "(nerfkit export KIND --help for its options)")
            return 0
        got = f" (got {argv[0]!r})" if argv else ""
        raise ConfigError(f"export needs a kind: nerfkit export mesh|pointcloud|cameras|splat RUN_DIR{got}")
    kind, rest = argv[0], argv[1:]
    prog = f"nerfkit export {kind}"
    if kind == "mesh":
        from nerfkit.export.mesh import export_mesh

        a = parse(ExportMeshArgs, rest, prog)
        if a.method != "levelset":
            given = [f for f in MESH_LEVELSET_FLAGS if any(x == f or x.startswith(f + "=") for x in rest)]
            if given:
                raise ConfigError(f"{given[0]} belongs to --method levelset (this export uses --method {a.method}); "
                                  f"drop it or pass --method levelset")
        if a.method == "levelset" and not a.visible_only and flag_value(rest, "--every") is not None:
            raise ConfigError("--every thins the training views of the visibility pass, which --no-visible-only "
                              "turns off; drop one of them")
        if not a.texture and "--texture-size" in " ".join(rest):
            raise ConfigError("--texture-size sets the texture of --texture; pass --texture too, or drop it")
        rec = export_mesh(a.run_dir, a.out, a.resolution, a.threshold, a.max_faces, a.visible_only, a.snap, a.every,
                          a.data, progress=a.progress, carve=a.carve, overwrite=a.overwrite, method=a.method,
                          box=a.box, watertight=a.watertight, texture=a.texture, texture_size=a.texture_size)
        closed = "closed manifold" if rec["closed_manifold"] else "open where no view saw the surface"
        files = rec["texture"]["files"] if "texture" in rec else [rec["file"]]
        print(f"wrote {', '.join(files)}: {rec['vertices']} vertices, {rec['faces']} faces, {closed} "
              f"({rec['method']}, {rec['seconds']:.1f} s)")
    elif kind == "pointcloud":
        from nerfkit.export.pointcloud import export_pointcloud

        a = parse(ExportPointcloudArgs, rest, prog)
        rec = export_pointcloud(a.run_dir, a.out, a.split, a.every, a.min_opacity, a.voxel_size, a.data, a.chunk,
                                progress=a.progress, overwrite=a.overwrite)
        print(f"wrote {rec['file']}: {rec['points']} points ({rec['seconds']:.1f} s)")
    elif kind == "splat":
        from nerfkit.export.splat import export_splat

        a = parse(ExportSplatArgs, rest, prog)
        rec = export_splat(a.run_dir, a.out, overwrite=a.overwrite)
        print(f"wrote {rec['file']}: {rec['gaussians']} Gaussians, SH degree {rec['sh_degree']} ({rec['seconds']:.1f} s)")
    else:
        from nerfkit.export.cameras import export_cameras

        a = parse(ExportCamerasArgs, rest, prog)
        rec = export_cameras(a.run_dir, a.out, a.split, a.data, overwrite=a.overwrite)
        print(f"wrote {rec['file']}: {rec['frames']} cameras")
    picture = Path(a.run_dir) / "exports" / rec["picture"]
    if (Path(a.run_dir) / "report.html").is_file():
        from nerfkit.report.run import write_report

        print(f"picture: {picture}, also in {write_report(a.run_dir)}")
    else:
        print(f"picture: {picture} (and in the run report: nerfkit report {a.run_dir})")
    return 0


