"""The `nerfkit` command line: demo, make-scene, train, eval, render.

Each verb is a typed dataclass parsed by tyro. `train` starts from a preset (`--preset`,
read before the rest so `--help` shows that preset's values) or, with `--resume`, from
the run folder's saved config; any single knob can then be overridden.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Literal

import tyro

from nerfkit.config import DEFAULT_PRESET, PRESET_HELP, PRESETS, Config, preset
from nerfkit.errors import ConfigError, NerfkitError

PresetName = Literal[tuple(PRESETS)]  # type: ignore[valid-type]


@dataclasses.dataclass
class TrainArgs:
    """Train a radiance field on a capture folder and write a run folder."""

    data_dir: tyro.conf.Positional[Path]
    """Capture folder: Blender (transforms_{split}.json), nerfstudio (transforms.json), LLFF (poses_bounds.npy)
    or COLMAP (sparse/0); `nerfkit process-data` makes one from photos or a video."""
    out: Path
    """Run folder (config, metrics, plots, validation images, checkpoints)."""
    preset: PresetName = DEFAULT_PRESET  # type: ignore[valid-type]
    """Starting configuration: ngp (default) | seed | nerf | demo | tiny (see README)."""
    resume: bool = False
    """Continue the run in --out from its newest checkpoint (with its saved config)."""
    progress: bool = True
    """Show a progress bar."""
    cfg: tyro.conf.OmitArgPrefixes[Config] = dataclasses.field(default_factory=Config)


@dataclasses.dataclass
class EvalArgs:
    """PSNR and SSIM of a trained run on a split; writes RUN_DIR/eval_<split>.json."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    data: Path | None = None
    """The data folder the views come from (default: the one the run was trained on)."""
    split: str = "test"
    """Views to evaluate: 'split' or 'split[a:b]', e.g. 'val[50:100]'."""
    downscale: int | None = None
    """Image downscale factor (default: the run's training resolution)."""
    every: int = 1
    """Evaluate every K-th view."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""


@dataclasses.dataclass
class RenderArgs:
    """Render a split's poses or an orbit: RGB and depth PNGs, depth .npy, MP4 videos."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    data: Path | None = None
    """The data folder (poses, field of view, the orbit's path); default: the one the run was trained on."""
    split: str | None = None
    """Render the poses of this split, e.g. 'val[50:100]'."""
    orbit: int | None = None
    """Render an orbit of N frames: a circle at the cameras' typical radius and elevation (Blender scenes),
    or an ellipse fitted to the camera centres (photo captures), looking at the scene centre."""
    width: int | None = None
    """Output width in pixels (default: training width; height follows the aspect ratio)."""
    height: int | None = None
    """Output height in pixels."""
    out: Path | None = None
    """Output folder (default: RUN_DIR/renders/<split-or-orbit>_<W>x<H>)."""
    camera_path: Path | None = None
    """Render a camera path: nerfstudio's camera_path.json layout (written by `nerfkit view` or nerfstudio's
    viewer); its frames, field of view, resolution and fps unless --width/--height/--fps are given."""
    fps: int | None = None
    """Video frame rate (default: the camera path's, else 24)."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""


@dataclasses.dataclass
class MakeSceneArgs:
    """Write nerfkit's procedural demo scene in Blender format (with exact depth maps)."""

    out_dir: tyro.conf.Positional[Path]
    """Folder to write transforms_{train,val,test}.json and the images into."""
    size: int = 64
    """Image width and height in pixels."""
    n_train: int = 60
    n_val: int = 10
    n_test: int = 10
    seed: int = 0


@dataclasses.dataclass
class DemoArgs:
    """Generate the procedural scene, train on it, evaluate on its test views, render an orbit video."""

    out: Path = Path("nerfkit-demo")
    """Folder for the scene and the run."""
    preset: PresetName = "demo"  # type: ignore[valid-type]
    """Model preset to train."""
    max_minutes: float = 3.0
    """Training time budget."""
    size: int = 256
    """Scene image size (training, evaluation and the orbit video)."""
    orbit_frames: int = 48
    """Frames in the orbit video."""


@dataclasses.dataclass
class ExperimentArgs:
    """Run an experiment. pe-ablation: train Model-1 (PE, L_xyz=10, L_dir=4), Model-2 (no PE) and
    Model-3 (PE, L_xyz=5, L_dir=2) with the same preset, seed and budget; evaluate, render orbits;
    write results.md/.json, overlaid curves, image grids and OUT/report.html."""

    experiment: tyro.conf.Positional[Literal["pe-ablation"]]
    """Which experiment: pe-ablation."""
    data_dir: tyro.conf.Positional[Path]
    """Folder with transforms_{split}.json and the images."""
    out: Path
    """Experiment folder (one run folder per model, results, plots, grids, report.html)."""
    budget_minutes: float | None = None
    """Wall-time budget per model, compile and validation included."""
    max_steps: int | None = None
    """Step budget per model (with --budget-minutes: whichever comes first)."""
    preset: PresetName = "seed"  # type: ignore[valid-type]
    """Configuration all three models start from (only the positional encoding differs)."""
    seed: int | None = None
    """Seed of all three models (default: the preset's)."""
    eval_every: int = 2
    """Evaluate every K-th view of the val split."""
    orbit_frames: int = 40
    """Frames of each model's orbit video (at the training resolution)."""
    grid_views: int = 2
    """Validation views shown in image grids (at least 2)."""
    val_every: int | None = None
    """Validate every N steps during training (default: the preset's)."""
    train_split: str | None = None
    """Frames to train on (default: the data's train split); the report's seed protocol is "train,val[0:50]"."""
    val_split: str | None = None
    """Frames to validate and evaluate on (default: val, else test); seed protocol: "val[50:100]"."""
    target_width: int | None = None
    """Shrink images to this width (seed protocol: 200)."""
    downscale: int | None = None
    """Shrink images by this factor (overrides --target-width)."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class ProcessArgs:
    """Recover camera poses from photos or a video with structure from motion (pycolmap, on the CPU) and
    write a capture folder that `nerfkit train` reads: transforms.json, images/, images_2/, images_4/,
    masks/, sparse_pc.ply, cameras.png (check it), colmap.log."""

    kind: tyro.conf.Positional[Literal["images", "video"]]
    """images: a folder of photos; video: one video file."""
    source: tyro.conf.Positional[Path]
    """The folder of photos (.jpg, .png, ...) or the video file."""
    out: Path
    """The capture folder to write (built aside and renamed when complete)."""
    masks: Path | None = None
    """Folder of object masks named like the photos (any extension, optional _mask suffix; white = object):
    SfM then sees only the object (needed for turntable captures) and training uses them as alpha."""
    camera_model: Literal["SIMPLE_RADIAL", "OPENCV", "PINHOLE"] = "SIMPLE_RADIAL"
    """One camera shared by all photos: SIMPLE_RADIAL (f, cx, cy, k), OPENCV (fx, fy, cx, cy, k1, k2, p1,
    p2; mapped with SIMPLE_RADIAL, then refined) or PINHOLE."""
    matching: Literal["auto", "exhaustive", "sequential"] = "auto"
    """auto: exhaustive up to 150 photos, sequential beyond and for videos (no loop closure: COLMAP's needs a
    downloaded vocabulary tree)."""
    frames: int = 120
    """video: number of frames to keep."""
    max_image_size: int = 1600
    """SIFT runs on photos shrunk to this longest side (poses stay in full-size pixels)."""
    overwrite: bool = False
    """Replace --out if it exists."""
    verbose: bool = False
    """Show COLMAP's log (otherwise kept in OUT/colmap.log)."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class ReportArgs:
    """Write a static HTML report that opens from disk: RUN_DIR/report.html for a run folder, or
    the experiment report for a folder written by `nerfkit experiment`."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train` (or an experiment folder)."""


def _flag_value(argv: list[str], flag: str) -> str | None:
    """The value given to `flag` ("--flag V" or "--flag=V"), read before tyro parses argv."""
    for k, a in enumerate(argv):
        if a == flag and k + 1 < len(argv):
            return argv[k + 1]
        if a.startswith(flag + "="):
            return a.split("=", 1)[1]
    return None


def cmd_train(argv: list[str]) -> int:
    from nerfkit.train import Trainer, load_run_config

    name = _flag_value(argv, "--preset") or DEFAULT_PRESET
    base = preset(name) if name in PRESETS else preset(DEFAULT_PRESET)
    out = _flag_value(argv, "--out")
    if "--resume" in argv and out and (Path(out) / "config.json").is_file():
        base = load_run_config(Path(out))  # a resumed run keeps its own config
    default = TrainArgs(data_dir=tyro.MISSING, out=tyro.MISSING, preset=name if name in PRESETS else DEFAULT_PRESET,
                        cfg=base)
    args = tyro.cli(TrainArgs, default=default, args=argv, prog="nerfkit train")
    res = Trainer(args.data_dir, args.out, args.cfg, resume=args.resume, progress=args.progress).run()
    val = f"{res.val_psnr:.2f} dB" if res.val_psnr is not None else "n/a"
    print(f"step {res.step}, {res.steps_per_second:.2f} steps/s, val PSNR {val}; run folder: {res.run_dir}")
    return 130 if res.interrupted else 0


def cmd_eval(argv: list[str]) -> int:
    from nerfkit.evaluate import evaluate_run, format_eval_table, split_slug

    a = tyro.cli(EvalArgs, args=argv, prog="nerfkit eval")
    res = evaluate_run(a.run_dir, a.data, a.split, a.downscale, a.every, a.chunk)
    print(format_eval_table(res))
    print(f"wrote {a.run_dir / ('eval_' + split_slug(a.split) + '.json')}")
    return 0


def cmd_render(argv: list[str]) -> int:
    from nerfkit.evaluate import render_run

    a = tyro.cli(RenderArgs, args=argv, prog="nerfkit render")
    info = render_run(a.run_dir, a.data, a.split, a.orbit, a.width, a.height, a.out, a.fps, a.chunk,
                      camera_path=a.camera_path)
    print(f"rendered {info['frames']} frames at {info['width']}x{info['height']} "
          f"({info['seconds_per_frame']:.2f} s/frame) into {info['out']} (rgb.mp4, depth.mp4)")
    return 0


def cmd_make_scene(argv: list[str]) -> int:
    from nerfkit.data.scene import make_scene

    a = tyro.cli(MakeSceneArgs, args=argv, prog="nerfkit make-scene")
    path = make_scene(a.out_dir, size=a.size, n_train=a.n_train, n_val=a.n_val, n_test=a.n_test, seed=a.seed)
    print(f"wrote the procedural scene to {path} ({a.n_train} train, {a.n_val} val, {a.n_test} test views, {a.size}px)")
    return 0


def cmd_demo(argv: list[str]) -> int:
    from nerfkit.data.scene import make_scene
    from nerfkit.evaluate import evaluate_run, format_eval_table, render_run
    from nerfkit.train import Trainer

    a = tyro.cli(DemoArgs, args=argv, prog="nerfkit demo")
    t0 = time.perf_counter()
    scene = make_scene(a.out / "scene", size=a.size)
    print(f"[1/4] procedural scene: {scene}")
    cfg = preset(a.preset)
    cfg.train.max_minutes = a.max_minutes
    run = a.out / "run"
    if (run / "checkpoints").is_dir():
        import shutil

        shutil.rmtree(run)  # the demo always starts fresh
    print(f"[2/4] training ({a.preset} preset, up to {a.max_minutes:g} min) into {run}")
    res = Trainer(scene, run, cfg).run()
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


def cmd_experiment(argv: list[str]) -> int:
    from nerfkit.experiments import pe_ablation

    a = tyro.cli(ExperimentArgs, args=argv, prog="nerfkit experiment")
    pe_ablation(a.data_dir, a.out, preset=a.preset, budget_minutes=a.budget_minutes, max_steps=a.max_steps,
                seed=a.seed, eval_every=a.eval_every, orbit_frames=a.orbit_frames, grid_views=a.grid_views,
                val_every=a.val_every, progress=a.progress, train_split=a.train_split, val_split=a.val_split,
                target_width=a.target_width, downscale=a.downscale)
    print("\n" + (a.out / "results.md").read_text())
    print(f"report: {a.out / 'report.html'}")
    return 0


def cmd_process_data(argv: list[str]) -> int:
    from nerfkit.process.capture import process_images, process_video
    from nerfkit.process.sfm import SfmOptions

    a = tyro.cli(ProcessArgs, args=argv, prog="nerfkit process-data")
    if a.max_image_size < 64:
        raise ConfigError(f"--max-image-size must be at least 64 (got {a.max_image_size})")
    opts = SfmOptions(camera_model=a.camera_model, max_image_size=a.max_image_size, verbose=a.verbose)
    common = dict(masks=a.masks, opts=opts, matching=a.matching, overwrite=a.overwrite, progress=a.progress)
    if a.kind == "images":
        process_images(a.source, a.out, **common)
    else:
        process_video(a.source, a.out, a.frames, **common)
    print(f"next: nerfkit train {a.out} --out runs/{a.out.name}")
    return 0


def cmd_report(argv: list[str]) -> int:
    from nerfkit.report import write_experiment_report, write_report

    a = tyro.cli(ReportArgs, args=argv, prog="nerfkit report")
    if (a.run_dir / "results.json").is_file() and not (a.run_dir / "config.json").is_file():
        path = write_experiment_report(a.run_dir)
    else:
        path = write_report(a.run_dir)
    print(f"wrote {path}")
    return 0


COMMANDS = {
    "demo": (cmd_demo, "generate the procedural scene, train, evaluate and render an orbit (a few minutes)"),
    "make-scene": (cmd_make_scene, "write the procedural demo scene in Blender format"),
    "process-data": (cmd_process_data, "poses from photos or a video (pycolmap SfM): nerfkit process-data images DIR "
                                       "--out DATA [--masks DIR]"),
    "train": (cmd_train, "train a radiance field: nerfkit train DATA_DIR --out RUN_DIR [--preset ngp|seed|nerf|demo]"),
    "eval": (cmd_eval, "PSNR/SSIM of a run on a split: nerfkit eval RUN_DIR --split SPLIT [--data DATA_DIR]"),
    "render": (cmd_render, "render poses or an orbit to PNGs + MP4: nerfkit render RUN_DIR --orbit N"),
    "experiment": (cmd_experiment, "compare models under one budget: nerfkit experiment pe-ablation DATA_DIR --out DIR "
                                   "--budget-minutes M"),
    "report": (cmd_report, "static HTML report of a run or experiment (opens from disk): nerfkit report RUN_DIR"),
}


def usage() -> str:
    lines = ["usage: nerfkit COMMAND [ARGS]  (nerfkit COMMAND --help for its options)", "", "commands:"]
    lines += [f"  {name:<13} {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "presets:"] + [f"  {k:<11} {v}" for k, v in PRESET_HELP.items()]
    return "\n".join(lines)


COMPILING = {"demo", "train", "eval", "render", "experiment"}


def enable_compile_cache() -> None:
    """Keep jit-compiled functions on disk between runs (JAX's persistent compilation cache), so
    the second `nerfkit render` of a model starts in seconds. $NERFKIT_COMPILE_CACHE names the
    folder (default ~/.cache/nerfkit/jax); "off" disables it."""
    path = os.environ.get("NERFKIT_COMPILE_CACHE", str(Path.home() / ".cache" / "nerfkit" / "jax"))
    if path.strip().lower() in ("", "0", "off", "none"):
        return
    import jax

    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


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


if __name__ == "__main__":
    sys.exit(main())
