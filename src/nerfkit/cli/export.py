"""`nerfkit export mesh|pointcloud|cameras|splat`: one kind per call, each its own flags."""

from __future__ import annotations

from pathlib import Path

from nerfkit.cli.args import (
    ExportCamerasArgs,
    ExportMeshArgs,
    ExportPointcloudArgs,
    ExportSplatArgs,
)
from nerfkit.cli.parsing import flag_value, parse
from nerfkit.core.errors import ConfigError

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


