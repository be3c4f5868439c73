"""The `nerfkit` command line: a thin layer that parses each verb's arguments and calls the library.

Each verb is a typed dataclass parsed by tyro (args.py; the export kinds' in export.py) and one cmd_*
function that parses, calls the library and prints; train and demo live in train.py, export in export.py,
the rest here. Every import that loads JAX is deferred into the cmd_* functions, so `nerfkit --help` and
refused flags answer in ~0.1 s.
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path

from nerfkit.cli.args import (
    BakeArgs,
    BenchmarkArgs,
    EvalArgs,
    ExperimentArgs,
    ImportSplatArgs,
    MakeMultiscaleArgs,
    MakeSceneArgs,
    ProcessArgs,
    RenderArgs,
    ReportArgs,
    ViewArgs,
    ViewBakedArgs,
)
from nerfkit.cli.export import cmd_export
from nerfkit.cli.hugepages import restart_with_huge_pages
from nerfkit.core.interrupts import exit_status, interrupts_raise, unblock_if_restarted
from nerfkit.cli.parsing import flag_value, parse
from nerfkit.cli.train import cmd_demo, cmd_train
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.outputs import check_new_folder
from nerfkit.core.presets import (
    PRESET_HELP,
)


def cmd_eval(argv: list[str]) -> int:
    from nerfkit.evaluation.evaluate import evaluate_run, format_eval_table

    a = parse(EvalArgs, argv, "nerfkit eval")
    res = evaluate_run(a.run_dir, a.data, a.split, a.downscale, a.every, a.chunk, baked=a.baked,
                       overwrite=a.overwrite, fit_poses=a.fit_poses, fit_colour=a.fit_colour)
    print(format_eval_table(res))
    print(f"wrote {res['written']}")
    return 0


def cmd_render(argv: list[str]) -> int:
    from nerfkit.evaluation.evaluate import render_run

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


# bake's flags that only the radiance-field bake reads (a splat run's page holds the Gaussians as they are).
FIELD_BAKE_ONLY = ("--resolution", "--sh-bands", "--finetune-minutes", "--max-mb")


def cmd_bake(argv: list[str]) -> int:
    from nerfkit.bake.bake import bake_run

    a = parse(BakeArgs, argv, "nerfkit bake")
    if (a.run_dir / "config.json").is_file():
        from nerfkit.models.registry import method_class
        from nerfkit.run.folder import RunFolder

        if method_class(RunFolder(a.run_dir).config()).supports.gaussians:  # a page that draws the Gaussians
            from nerfkit.bake.splat_web import write_splat_page

            for flag in FIELD_BAKE_ONLY:
                if flag_value(argv, flag) is not None:
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
    from nerfkit.data.formats.multiscale import make_multiscale

    a = parse(MakeMultiscaleArgs, argv, "nerfkit make-multiscale")
    info = make_multiscale(a.data_dir, a.out, a.levels, a.progress)
    print(f"wrote {info['images']} images ({', '.join(info['splits'])} at {a.levels} scales) and metadata.json to "
          f"{a.out}; evaluate every scale with nerfkit eval RUN --data {a.out} --split SPLIT")
    return 0


def cmd_make_scene(argv: list[str]) -> int:
    from nerfkit.data.procedural.scene import make_scene

    a = parse(MakeSceneArgs, argv, "nerfkit make-scene")
    check_new_folder(a.out_dir, a.overwrite, "OUT_DIR")
    path = make_scene(a.out_dir, size=a.size, n_train=a.n_train, n_val=a.n_val, n_test=a.n_test, seed=a.seed)
    print(f"wrote the procedural scene to {path} ({a.n_train} train, {a.n_val} val, {a.n_test} test views, {a.size}px)")
    return 0


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
    from nerfkit.experiments.benchmark import benchmark

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


def cmd_import(argv: list[str]) -> int:
    from nerfkit.models.splat.formats import readable

    if not argv or argv[0] != "splat":
        if argv and argv[0] in ("-h", "--help"):
            print(f"usage: nerfkit import splat FILE --out RUN_DIR [--data CAPTURE]  ({', '.join(readable())}; "
                  f"nerfkit import splat --help for its options)")
            return 0
        got = f" (got {argv[0]!r})" if argv else ""
        raise ConfigError(f"import needs a kind: nerfkit import splat FILE --out RUN_DIR{got}")
    a = parse(ImportSplatArgs, argv[1:], "nerfkit import splat")
    from nerfkit.run.imported import import_splat

    import_splat(a.file, a.out, a.data, a.overwrite)
    run = shlex.quote(str(a.out))
    print(f"run folder: {a.out}\nnext: nerfkit view {run}, nerfkit render {run} --orbit 60, nerfkit eval {run}")
    return 0


def cmd_report(argv: list[str]) -> int:
    from nerfkit.experiments.report import write_experiment_report
    from nerfkit.report.run import write_report

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
    "import": (cmd_import, "a splat file someone else made (.ply, .spz, .splat, .glb, .sog) as a run folder to view, render, "
                           "bake, score and fine-tune: nerfkit import splat FILE --out RUN_DIR [--data CAPTURE]"),
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


COMPILING = {"demo", "train", "eval", "render", "experiment", "view", "export", "import", "bake", "benchmark"}


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
    from_command_line = argv is None  # `nerfkit ...` or `python -m nerfkit ...`, not a caller's main([...])
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(usage())
        return 0 if argv else 2
    verb, rest = argv[0], argv[1:]
    if verb not in COMMANDS:
        print(f"nerfkit: error: unknown command {verb!r}; `nerfkit --help` lists the commands", file=sys.stderr)
        return 1
    with interrupts_raise():
        return run_verb(verb, rest, from_command_line)


def run_verb(verb: str, rest: list[str], from_command_line: bool) -> int:
    """Run one verb; what stopped it, in one line and an exit status (1 for an error, 128 + N for signal N)."""
    try:
        unblock_if_restarted()  # (`python -c "...main()"` restarted: command_line did not run)
        if verb in COMPILING and "--help" not in rest and "-h" not in rest:
            if from_command_line:
                restart_with_huge_pages()  # returns where it changes nothing (hugepages.py)
            enable_compile_cache()
        return COMMANDS[verb][0](rest)
    except NerfkitError as e:
        print(f"nerfkit {verb}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:  # Ctrl-C or SIGTERM (core/interrupts.py)
        status, words = exit_status(e)
        print(f"nerfkit {verb}: {words}", file=sys.stderr)
        return status
    except BrokenPipeError:  # the reader of our output went away: not the verb's error (cli/entry.py)
        raise
    except OSError as e:  # the machine said no: a path that is a file, no permission, a full disk
        where = f" ({e.filename})" if e.filename else ""
        print(f"nerfkit {verb}: error: {e.strerror or e}{where}; check that path (for an output: another --out, "
              f"or free space or permissions there)", file=sys.stderr)
        return 1
    except MemoryError as e:  # numpy names what it could not allocate
        print(f"nerfkit {verb}: error: out of memory ({e}); lower the size, resolution or count asked for",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
