"""The `nerfkit` command line: a thin layer that parses each verb's arguments and calls the library.

Each verb is a typed dataclass parsed by tyro (cli_args.py). `train` starts from a preset (`--preset`,
read before the rest so `--help` shows that preset's values) or, with `--resume`, from
the run folder's saved config; any single knob can then be overridden.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shlex
import sys
import time
from pathlib import Path

import tyro

from nerfkit.cli_args import (
    BakeArgs,
    BenchmarkArgs,
    DemoArgs,
    EvalArgs,
    ExportCamerasArgs,
    ExportMeshArgs,
    ExportPointcloudArgs,
    ExportSplatArgs,
    ExperimentArgs,
    MakeMultiscaleArgs,
    MakeSceneArgs,
    ProcessArgs,
    RenderArgs,
    ReportArgs,
    TrainArgs,
    ViewArgs,
    ViewBakedArgs,
)
from nerfkit.config import DEFAULT_PRESET, PRESET_HELP, PRESETS, preset, set_budget
from nerfkit.errors import ConfigError, NerfkitError
from nerfkit.flags import explicit_settings
from nerfkit.outputs import check_new_folder


def _one_line(text: str, prog: str) -> str:
    """tyro's boxed parse error as one line: the message, its first suggestion, and where the help is."""
    sections, cur = [], []
    for raw in text.splitlines():
        if raw.lstrip().startswith(("╭", "╰")):  # the box's title and bottom
            continue
        line = raw.strip().strip("│").rstrip()
        line = line[1:] if line.startswith(" ") else line  # the box's inner margin
        if not line.strip() or set(line.strip()) <= set("─╭╮╰╯ "):
            if cur and set(line.strip()) <= set("─ ") and line.strip():
                sections.append(cur)
                cur = []
            continue
        cur.append(line)
    if cur:
        sections.append(cur)
    if not sections:
        return f"invalid arguments; see {prog} --help"
    first = sections[0]
    if first[0].startswith("Missing from"):
        names = [x.strip() for x in first[1:] if x.startswith("    ") and not x.startswith("     ")]
        msg = "missing " + ", ".join(names or [" ".join(x.strip() for x in first[1:])])
    elif first[0].startswith("Unrecognized options"):
        msg = first[0]
    else:
        msg = " ".join(x.strip() for x in first)
    for sec in sections[1:]:
        if sec[0].strip().startswith("Perhaps you meant") and len(sec) > 1:
            msg += f"; perhaps you meant {sec[1].split()[0]}"
    return f"{msg.rstrip('.')}; see {prog} --help"


def parse(cls, argv: list[str], prog: str, default=None):
    """tyro.cli, with a parse error turned into one ConfigError line (exit 1 in main) instead of a box."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return tyro.cli(cls, args=argv, prog=prog, default=default)
    except SystemExit as e:
        if e.code in (0, None):
            raise
        raise ConfigError(_one_line(err.getvalue(), prog)) from None


def _flag_value(argv: list[str], flag: str) -> str | None:
    """The value given to `flag` ("--flag V" or "--flag=V"), read before tyro parses argv."""
    for k, a in enumerate(argv):
        if a == flag and k + 1 < len(argv):
            return argv[k + 1]
        if a.startswith(flag + "="):
            return a.split("=", 1)[1]
    return None


def parse_train_args(argv: list[str]) -> TrainArgs:
    """`nerfkit train` arguments: the preset's config (or, with --resume, the run's own) with the flags on top."""
    from nerfkit.train import load_run_config

    name = _flag_value(argv, "--preset") or DEFAULT_PRESET
    base = preset(name) if name in PRESETS else preset(DEFAULT_PRESET)
    out = _flag_value(argv, "--out")
    if "--resume" in argv and out and (Path(out) / "config.json").is_file():
        base = load_run_config(Path(out))  # a resumed run keeps its own config
    default = TrainArgs(data_dir=tyro.MISSING, out=tyro.MISSING, preset=name if name in PRESETS else DEFAULT_PRESET,
                        cfg=base)
    args = parse(TrainArgs, argv, "nerfkit train", default=default)
    given = explicit_settings(argv)
    if "train.max_steps" in given and "train.max_minutes" not in given:
        args.cfg.train.max_minutes = None  # a step budget alone replaces the preset's time budget
    return args


def cmd_train(argv: list[str]) -> int:
    from nerfkit.train import Trainer

    if any(a in ("-h", "--help", "--help-all") for a in argv):
        from nerfkit.cli_help import train_help

        name = _flag_value(argv, "--preset") or DEFAULT_PRESET
        if name not in PRESETS:
            raise ConfigError(f"--preset {name}: no such preset; pick one of {', '.join(PRESETS)}")
        print(train_help(name, full="--help-all" in argv))
        return 0
    args = parse_train_args(argv)
    from nerfkit.parallel import init_distributed, is_primary

    if init_distributed() > 1 and args.viewer:
        raise ConfigError("--viewer: not in a multi-process run; view the run folder with `nerfkit view` instead")
    trainer = Trainer(args.data_dir, args.out, args.cfg, resume=args.resume, progress=args.progress and is_primary(),
                      overwrite=args.overwrite, given=explicit_settings(argv), preset=args.preset)
    if args.viewer:
        from nerfkit.viewer.run import attach_viewer

        attach_viewer(trainer, args.viewer_host, args.viewer_port)
    try:
        res = trainer.run()
        val = f"{res.val_psnr:.2f} dB" if res.val_psnr is not None else "n/a"
        print(f"step {res.step}, {res.steps_per_second:.2f} steps/s, val PSNR {val}; run folder: {res.run_dir}")
        if not res.interrupted:
            print(f"next: nerfkit render {shlex.quote(str(res.run_dir))} --orbit 60")
        if trainer.viewer is not None and not res.interrupted:
            from nerfkit.viewer.run import linger

            linger(trainer.viewer)
    finally:
        if trainer.viewer is not None:
            trainer.viewer.close()
    return 130 if res.interrupted else 0


def cmd_eval(argv: list[str]) -> int:
    from nerfkit.evaluate import evaluate_run, format_eval_table

    a = parse(EvalArgs, argv, "nerfkit eval")
    res = evaluate_run(a.run_dir, a.data, a.split, a.downscale, a.every, a.chunk, baked=a.baked,
                       overwrite=a.overwrite)
    print(format_eval_table(res))
    print(f"wrote {res['written']}")
    return 0


def cmd_render(argv: list[str]) -> int:
    from nerfkit.evaluate import render_run

    a = parse(RenderArgs, argv, "nerfkit render")
    info = render_run(a.run_dir, a.data, a.split, a.orbit, a.width, a.height, a.out, a.fps, a.chunk,
                      camera_path=a.camera_path, overwrite=a.overwrite)
    print(f"rendered {info['frames']} frames at {info['width']}x{info['height']} "
          f"({info['seconds_per_frame']:.2f} s/frame) into {info['out']} (rgb.mp4, depth.mp4)")
    if info.get("width_capped_from"):
        print(f"note: orbits are rendered at most {info['width']} px wide unless you say otherwise; "
              f"--width {info['width_capped_from']} renders the training size")
    return 0


def cmd_view(argv: list[str]) -> int:
    if any(x == "--baked" or x.startswith("--baked=") for x in argv):
        from nerfkit.bake.web import serve_baked

        b = parse(ViewBakedArgs, argv, "nerfkit view")
        serve_baked(b.baked, b.host, b.port)
        return 0
    from nerfkit.viewer.run import view_run

    a = parse(ViewArgs, argv, "nerfkit view")
    view_run(a.run_dir, a.host, a.port, a.chunk)
    return 0


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
        if a.method == "levelset" and not a.visible_only and _flag_value(rest, "--every") is not None:
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
        from nerfkit.report import write_report

        print(f"picture: {picture}, also in {write_report(a.run_dir)}")
    else:
        print(f"picture: {picture} (and in the run report: nerfkit report {a.run_dir})")
    return 0


# bake's flags that only the radiance-field bake reads (a splat run's page holds the Gaussians as they are).
FIELD_BAKE_ONLY = ("--resolution", "--sh-bands", "--finetune-minutes", "--max-mb")


def cmd_bake(argv: list[str]) -> int:
    from nerfkit.bake.bake import bake_run

    a = parse(BakeArgs, argv, "nerfkit bake")
    if (a.run_dir / "config.json").is_file():
        from nerfkit.train import load_run_config

        if load_run_config(a.run_dir).field.kind == "splat":
            from nerfkit.splat.web import write_splat_page

            for flag in FIELD_BAKE_ONLY:
                if _flag_value(argv, flag) is not None:
                    raise ConfigError(f"{flag} has no effect on a splat run (its page draws the Gaussians "
                                      f"themselves, no grid or fine-tuning); drop it")
            write_splat_page(a.run_dir, a.out, overwrite=a.overwrite)
            print(f"next: nerfkit view --baked {shlex.quote(str(a.out))}")
            return 0
    bake_run(a.run_dir, a.out, a.resolution, a.sh_bands, a.finetune_minutes, a.max_mb, progress=a.progress,
             overwrite=a.overwrite)
    print(f"next: nerfkit view --baked {shlex.quote(str(a.out))}")
    print(f"next: nerfkit eval {shlex.quote(str(a.run_dir))} --baked {shlex.quote(str(a.out))}")
    return 0


def cmd_make_multiscale(argv: list[str]) -> int:
    from nerfkit.data.multiscale import make_multiscale

    a = parse(MakeMultiscaleArgs, argv, "nerfkit make-multiscale")
    info = make_multiscale(a.data_dir, a.out, a.levels, a.progress)
    print(f"wrote {info['images']} images ({', '.join(info['splits'])} at {a.levels} scales) and metadata.json to "
          f"{a.out}; evaluate every scale with nerfkit eval RUN --data {a.out} --split SPLIT")
    return 0


def cmd_make_scene(argv: list[str]) -> int:
    from nerfkit.data.scene import make_scene

    a = parse(MakeSceneArgs, argv, "nerfkit make-scene")
    check_new_folder(a.out_dir, a.overwrite, "OUT_DIR")
    path = make_scene(a.out_dir, size=a.size, n_train=a.n_train, n_val=a.n_val, n_test=a.n_test, seed=a.seed)
    print(f"wrote the procedural scene to {path} ({a.n_train} train, {a.n_val} val, {a.n_test} test views, {a.size}px)")
    return 0


def cmd_demo(argv: list[str]) -> int:
    from nerfkit.data.scene import make_scene
    from nerfkit.evaluate import evaluate_run, format_eval_table, render_run
    from nerfkit.train import Trainer, run_files

    a = parse(DemoArgs, argv, "nerfkit demo")
    t0 = time.perf_counter()
    run, scene_dir = a.out / "run", a.out / "scene"
    check_new_folder(scene_dir, a.overwrite, "--out")
    if (run_files(run) or (a.out / "demo_summary.json").exists()) and not a.overwrite:
        raise ConfigError(f"--out {a.out}: holds an earlier demo run ({run}); pass --overwrite to start again, or "
                          f"pick another --out")
    cfg = preset(a.preset)
    set_budget(cfg, a.max_minutes if a.max_steps is None or _flag_value(argv, "--max-minutes") is not None else None,
               a.max_steps)
    scene = make_scene(scene_dir, size=a.size)
    print(f"[1/4] procedural scene: {scene}")
    budget = " or ".join(x for x in (f"{cfg.train.max_minutes:g} min" if cfg.train.max_minutes else "",
                                     f"{cfg.train.max_steps} steps" if a.max_steps is not None else "") if x)
    print(f"[2/4] training ({a.preset} preset, up to {budget}) into {run}")
    res = Trainer(scene, run, cfg, overwrite=a.overwrite).run()
    print("[3/4] evaluating on the test views")
    ev = evaluate_run(run, scene, "test")
    print(format_eval_table(ev))
    print(f"[4/4] rendering a {a.orbit_frames}-frame orbit")
    info = render_run(run, scene, orbit=a.orbit_frames)
    summary = {
        "scene": str(scene), "run": str(run), "steps": res.step, "steps_per_second": round(res.steps_per_second, 2),
        "val_psnr": res.val_psnr, "test_psnr": ev["psnr"], "test_ssim": ev["ssim"],
        "videos": [str(Path(info["out"]) / "rgb.mp4"), str(Path(info["out"]) / "depth.mp4")],
        "plots": str(run / "plots"), "minutes": round((time.perf_counter() - t0) / 60, 2),
    }
    (a.out / "demo_summary.json").write_text(json.dumps(summary, indent=2))
    from nerfkit.report import write_report

    report = write_report(run)
    print("\nnerfkit demo finished in {minutes} min: test PSNR {test_psnr:.2f} dB, SSIM {test_ssim:.3f}".format(**summary))
    print(f"  run folder : {run}  (config, metrics.jsonl, plots/, val/, checkpoints/)")
    print(f"  test views : {run / 'eval_test'}  and {run / 'eval_test.json'}")
    print(f"  videos     : {summary['videos'][0]}  {summary['videos'][1]}")
    print(f"  report     : {report}  (open it in a browser)")
    return 0


# Flags that only one experiment reads (the other refuses them).
EXPERIMENT_ONLY = {"pe-ablation": ("--preset", "--orbit-frames", "--target-width", "--downscale"),
                   "antialias": ("--models", "--mlp-size")}


def cmd_experiment(argv: list[str]) -> int:
    from nerfkit.experiments import antialias_experiment, pe_ablation

    a = parse(ExperimentArgs, argv, "nerfkit experiment")
    for flag in EXPERIMENT_ONLY["pe-ablation" if a.experiment == "antialias" else "antialias"]:
        if any(x == flag or x.startswith(flag + "=") for x in argv):
            why = ("its models and the data's scales are fixed" if a.experiment == "antialias" else
                   "its three models are MLPs of the preset, differing only in the encoding")
            raise ConfigError(f"{flag} does not apply to the {a.experiment} experiment ({why}); drop it "
                              f"(see nerfkit experiment --help)")
    if a.experiment == "antialias":
        models = [m.strip() for m in a.models.split(",") if m.strip()] if a.models else None
        antialias_experiment(a.data_dir, a.out, a.budget_minutes, a.max_steps, models=models, mlp_size=a.mlp_size,
                             seed=a.seed,
                             eval_every=5 if a.eval_every is None else a.eval_every,
                             grid_views=1 if a.grid_views is None else a.grid_views,
                             val_every=a.val_every, train_split=a.train_split, val_split=a.val_split,
                             progress=a.progress)
    else:
        pe_ablation(a.data_dir, a.out, preset=a.preset, budget_minutes=a.budget_minutes, max_steps=a.max_steps,
                    seed=a.seed, eval_every=2 if a.eval_every is None else a.eval_every, orbit_frames=a.orbit_frames,
                    grid_views=2 if a.grid_views is None else a.grid_views,
                    val_every=a.val_every, progress=a.progress, train_split=a.train_split, val_split=a.val_split,
                    target_width=a.target_width, downscale=a.downscale)
    print("\n" + (a.out / "results.md").read_text())
    print(f"report: {a.out / 'report.html'}")
    return 0


def cmd_benchmark(argv: list[str]) -> int:
    from nerfkit.benchmark import benchmark

    a = parse(BenchmarkArgs, argv, "nerfkit benchmark")
    out = a.out if a.out is not None else Path("runs") / f"benchmark_{a.root.resolve().name}_{a.preset}"
    table = benchmark(a.root, out, preset=a.preset, budget_minutes=a.budget_minutes, max_steps=a.max_steps,
                      jobs=a.jobs, only=a.only, eval_every=a.eval_every, progress=a.progress, overwrite=a.overwrite)
    if a.only is None:
        print("\n" + (out / "results.md").read_text())
    if table["failed"]:
        raise NerfkitError(f"{len(table['failed'])} of {len(table['scenes'])} scene(s) failed "
                           f"({', '.join(table['failed'])}); the table marks them")
    return 0


def cmd_process_data(argv: list[str]) -> int:
    from nerfkit.process.capture import process_images, process_video
    from nerfkit.process.sfm import SfmOptions

    a = parse(ProcessArgs, argv, "nerfkit process-data")
    if a.kind == "images" and any(x == "--frames" or x.startswith("--frames=") for x in argv):
        raise ConfigError("--frames applies to `process-data video` (frames kept from the video); every photo of "
                          "a folder is used: drop it")
    if a.max_image_size < 64:
        raise ConfigError(f"--max-image-size must be at least 64 (got {a.max_image_size})")
    opts = SfmOptions(camera_model=a.camera_model, max_image_size=a.max_image_size, verbose=a.verbose)
    common = dict(masks=a.masks, opts=opts, matching=a.matching, overwrite=a.overwrite, progress=a.progress)
    if a.kind == "images":
        process_images(a.source, a.out, **common)
    else:
        process_video(a.source, a.out, a.frames, **common)
    print(f"next: nerfkit train {shlex.quote(str(a.out))} --out {shlex.quote('runs/' + a.out.name)}")
    return 0


def cmd_report(argv: list[str]) -> int:
    from nerfkit.report import write_experiment_report, write_report

    a = parse(ReportArgs, argv, "nerfkit report")
    if (a.run_dir / "results.json").is_file() and not (a.run_dir / "config.json").is_file():
        path = write_experiment_report(a.run_dir)
    else:
        path = write_report(a.run_dir)
    print(f"wrote {path}")
    return 0


COMMANDS = {
    "demo": (cmd_demo, "generate the procedural scene, train, evaluate and render an orbit (a few minutes)"),
    "make-scene": (cmd_make_scene, "write the procedural demo scene in Blender format"),
    "make-multiscale": (cmd_make_multiscale, "a Blender scene at 1, 1/2, 1/4, 1/8 resolution (mip-NeRF's multiscale "
                                             "layout): nerfkit make-multiscale DATA --out DATA_MS"),
    "process-data": (cmd_process_data, "poses from photos or a video (pycolmap SfM): nerfkit process-data images DIR "
                                       "--out DATA [--masks DIR]"),
    "train": (cmd_train, "train a radiance field or Gaussian splats: nerfkit train DATA_DIR --out RUN_DIR [--preset ngp|seed|nerf|splat|demo]"),
    "eval": (cmd_eval, "PSNR/SSIM of a run on a split: nerfkit eval RUN_DIR --split SPLIT [--data DATA_DIR]"),
    "render": (cmd_render, "render poses or an orbit to PNGs + MP4: nerfkit render RUN_DIR --orbit N"),
    "view": (cmd_view, "interactive viewer in the browser (viser): nerfkit view RUN_DIR [--port 7007]; "
                       "or nerfkit train ... --viewer; a baked scene's WebGL page: nerfkit view --baked DIR"),
    "export": (cmd_export, "mesh, point cloud, cameras or Gaussian splats in standard formats: nerfkit export "
                           "mesh|pointcloud|cameras|splat RUN_DIR [--out FILE]"),
    "bake": (cmd_bake, "a web page that renders a trained scene in real time in any browser (WebGL2): "
                       "nerfkit bake RUN_DIR --out DIR"),
    "experiment": (cmd_experiment, "compare models under one budget: nerfkit experiment pe-ablation|antialias "
                                   "DATA_DIR --out DIR --budget-minutes M"),
    "benchmark": (cmd_benchmark, "train and evaluate every scene under a folder, one table: nerfkit benchmark ROOT "
                                 "--preset P --budget-minutes M [--jobs K]"),
    "report": (cmd_report, "static HTML report of a run or experiment (opens from disk): nerfkit report RUN_DIR"),
}


def usage() -> str:
    lines = ["usage: nerfkit COMMAND [ARGS]  (nerfkit COMMAND --help for its options)", "", "commands:"]
    lines += [f"  {name:<13} {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "presets:"] + [f"  {k:<11} {v}" for k, v in PRESET_HELP.items()]
    return "\n".join(lines)


COMPILING = {"demo", "train", "eval", "render", "experiment", "view", "export", "bake", "benchmark"}


def enable_compile_cache() -> None:
    """Keep jit-compiled functions on disk between runs (JAX's persistent compilation cache), so
    the second `nerfkit render` of a model starts in seconds. $NERFKIT_COMPILE_CACHE names the
    folder (default ~/.cache/nerfkit/jax); "off" disables it."""
    path = os.environ.get("NERFKIT_COMPILE_CACHE", str(Path.home() / ".cache" / "nerfkit" / "jax"))
    if path.strip().lower() in ("", "0", "off", "none"):
        return
    import jax

    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(usage())
        return 0 if argv else 2
    verb, rest = argv[0], argv[1:]
    if verb not in COMMANDS:
        print(f"nerfkit: unknown command {verb!r}\n\n{usage()}", file=sys.stderr)
        return 2
    if verb in COMPILING and "--help" not in rest and "-h" not in rest:
        enable_compile_cache()
    try:
        return COMMANDS[verb][0](rest)
    except NerfkitError as e:
        print(f"nerfkit {verb}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"nerfkit {verb}: aborted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of our output went away (`nerfkit train --help | head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
