"""`nerfkit train` and `nerfkit demo`: train a run folder (and, for the demo, evaluate and render it)."""

from __future__ import annotations

import errno
import functools
import json
import shlex
import time
from pathlib import Path

import tyro

from nerfkit.cli.args import (
    DemoArgs,
    TrainArgs,
)
from nerfkit.cli.parsing import flag_value, parse
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.outputs import check_new_folder
from nerfkit.core.presets import (
    DEFAULT_PRESET,
    PRESETS,
    preset,
    set_budget,
)
from nerfkit.training.flags import explicit_settings


def preset_of(argv: list[str]) -> str:
    """The --preset of argv (read before tyro parses, so help and defaults follow it), or ConfigError."""
    name = flag_value(argv, "--preset") or DEFAULT_PRESET
    if name not in PRESETS:
        raise ConfigError(f"--preset {name}: no such preset; pick one of {', '.join(PRESETS)}")
    return name


@functools.cache
def _unset_words() -> dict[str, str]:
    """{flag: the word help prints for it unset} of every setting whose type is a number or None, and of a text
    setting that help shows unset as "-" (--init -: no file)."""
    import typing

    from nerfkit.cli.help import UNSET
    from nerfkit.core.config import Config
    from nerfkit.training.flags import flag_of, setting_names

    numeric = {}
    hints = {name: typing.get_type_hints(cls) for name, cls in Config.sections().items()}
    for name in setting_names():
        section, field = name.split(".")
        kinds = set(typing.get_args(hints[section][field]))
        if kinds in ({int, type(None)}, {float, type(None)}) or (kinds == {str, type(None)} and UNSET.get(name) == "-"):
            numeric[flag_of(name)] = UNSET.get(name, "auto")
    return numeric


def unset_words(argv: list[str]) -> list[str]:
    """argv with the word help prints for an unset number ("--bound auto", "--devices all", "--target-width -")
    turned into the None that tyro reads, so every value --help shows can be typed back."""
    numeric = _unset_words()
    out = list(argv)
    for k, a in enumerate(out):
        flag, eq, value = a.partition("=")
        if eq and numeric.get(flag) == value:  # --bound=auto
            out[k] = f"{flag}=None"
        elif k + 1 < len(out) and numeric.get(a) == out[k + 1]:  # --bound auto
            out[k + 1] = "None"
    return out


def parse_train_args(argv: list[str]) -> TrainArgs:
    """`nerfkit train` arguments: the preset's config (or, with --resume, the run's own) with the flags on top."""
    argv = unset_words(argv)
    name = preset_of(argv)
    base = preset(name)
    out = flag_value(argv, "--out")
    if "--resume" in argv and out and (Path(out) / "config.json").is_file():
        from nerfkit.run.folder import RunFolder

        base = RunFolder(Path(out)).config()  # a resumed run keeps its own config
        if flag_value(argv, "--preset") is not None and preset(name).field.kind != base.field.kind:
            raise ConfigError(f"--preset {name}: the run in {out} is a {base.field.kind} run and --resume keeps "
                              f"its own model (config.json); drop --preset, or start a new run with another --out")
    default = TrainArgs(data_dir=tyro.MISSING, out=tyro.MISSING, preset=name, cfg=base)
    args = parse(TrainArgs, argv, "nerfkit train", default=default)
    from nerfkit.models.registry import METHODS

    if args.cfg.field.kind not in METHODS:
        raise ConfigError(f"--kind {args.cfg.field.kind}: no such method; pick one of {', '.join(METHODS)}")
    given = explicit_settings(argv)
    if "train.max_steps" in given and "train.max_minutes" not in given:
        args.cfg.train.max_minutes = None  # a step budget alone replaces the preset's time budget
    return args


def stopped_by(e: OSError, data_dir: Path, trainer) -> NerfkitError:
    """The one line for a run that a write stopped (a full disk, a folder that went away): the failure, the
    newest checkpoint the run keeps, and the command that goes on from it (or starts again without one)."""
    from nerfkit.training import checkpoint as ckpt_lib

    last = ckpt_lib.latest_checkpoint(trainer.ckpt_dir)
    where = f" ({e.filename})" if e.filename else ""
    mend = "free space there" if e.errno in (errno.ENOSPC, errno.EDQUOT) else "mend that"
    again = f"nerfkit train {shlex.quote(str(data_dir))} --out {shlex.quote(str(trainer.run_dir))}"
    if last is None:
        return NerfkitError(f"{e.strerror or e}{where}; no checkpoint was saved: {mend}, then {again} --overwrite")
    return NerfkitError(f"{e.strerror or e}{where}; the run keeps its checkpoint of step "
                        f"{ckpt_lib.checkpoint_step(last)}: {mend}, then {again} --resume")


def cmd_train(argv: list[str]) -> int:
    from nerfkit.training.setup import refuse_given, refuse_spent_steps
    from nerfkit.training.trainer import Trainer

    if any(a in ("-h", "--help", "--help-all") for a in argv):
        from nerfkit.cli.help import train_help

        print(train_help(preset_of(argv), full="--help-all" in argv))
        return 0
    args = parse_train_args(argv)
    from nerfkit.training.parallel import init_distributed, is_primary

    if init_distributed() > 1 and args.viewer:
        raise ConfigError("--viewer: not in a multi-process run; view the run folder with `nerfkit view` instead")
    if args.viewer:  # a --viewer-host or --viewer-port it cannot use: before the data loads
        from nerfkit.viewer.run import check_address

        check_address(args.viewer_host, args.viewer_port, ("--viewer-host", "--viewer-port"))
    given = explicit_settings(argv)
    refuse_given(args.data_dir, args.cfg, given, args.preset, args.resume)
    if args.resume and "train.max_steps" in given:
        refuse_spent_steps(args.out, args.cfg.train.max_steps)
    trainer = Trainer(args.data_dir, args.out, args.cfg, resume=args.resume, progress=args.progress and is_primary(),
                      overwrite=args.overwrite)
    default_budget = not given.keys() & {"train.max_minutes", "train.max_steps"} and not args.resume
    if default_budget and args.progress and is_primary():
        print(f"budget: the {args.preset or 'preset'} default; --max-minutes M or --max-steps N changes it", flush=True)
    viewer = None
    if args.viewer:
        from nerfkit.viewer.run import attach_viewer

        viewer = attach_viewer(trainer, args.viewer_host, args.viewer_port)
    try:
        try:
            res = trainer.run()
        except OSError as e:  # the machine stopped the run (a full disk): what it keeps, and how to go on
            raise stopped_by(e, args.data_dir, trainer) from None
        from nerfkit.report.run import write_report_or_warn

        if is_primary():
            write_report_or_warn(res.run_dir)
        val = f"{res.val_psnr:.2f} dB" if res.val_psnr is not None else "n/a"
        print(f"step {res.step}, {res.steps_per_second:.2f} steps/s, val PSNR {val}; run folder: {res.run_dir}")
        if not res.interrupted:
            print(f"next: nerfkit render {shlex.quote(str(res.run_dir))} --orbit 60")
        if viewer is not None and not res.interrupted:
            from nerfkit.viewer.run import linger

            linger(viewer)
    finally:
        if viewer is not None:
            viewer.close()
    return 130 if res.interrupted else 0


def cmd_demo(argv: list[str]) -> int:
    from nerfkit.core.config import validate
    from nerfkit.data.procedural.scene import MAX_SIZE, make_scene
    from nerfkit.evaluation.evaluate import evaluate_run, format_eval_table, render_run
    from nerfkit.training.setup import run_files
    from nerfkit.training.trainer import Trainer

    a = parse(DemoArgs, argv, "nerfkit demo")
    t0 = time.perf_counter()
    run, scene_dir = a.out / "run", a.out / "scene"
    check_new_folder(scene_dir, a.overwrite, "--out")
    if (run_files(run) or (a.out / "demo_summary.json").exists()) and not a.overwrite:
        raise ConfigError(f"--out {a.out}: holds an earlier demo run ({run}); pass --overwrite to start again, or "
                          f"pick another --out")
    cfg = preset(a.preset)
    set_budget(cfg, a.max_minutes if a.max_steps is None or flag_value(argv, "--max-minutes") is not None else None,
               a.max_steps)
    validate(cfg)  # every flag checked before the scene is written
    if not 1 <= a.size <= MAX_SIZE or a.orbit_frames < 1:
        raise ConfigError(f"--size must be 1-{MAX_SIZE} and --orbit-frames at least 1 (got {a.size} and "
                          f"{a.orbit_frames})")
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
    from nerfkit.report.run import write_report

    report = write_report(run)
    print("\nnerfkit demo finished in {minutes} min: test PSNR {test_psnr:.2f} dB, SSIM {test_ssim:.3f}".format(**summary))
    print(f"  run folder : {run}  (config, metrics.jsonl, plots/, val/, checkpoints/)")
    print(f"  test views : {run / 'eval_test'}  and {run / 'eval_test.json'}")
    print(f"  videos     : {summary['videos'][0]}  {summary['videos'][1]}")
    print(f"  report     : {report}  (open it in a browser)")
    return 0


# Flags that only one experiment reads (the other refuses them).
