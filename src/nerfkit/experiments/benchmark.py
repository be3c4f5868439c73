"""`nerfkit benchmark ROOT`: train and evaluate every scene folder under ROOT with one preset and budget.

A scene is any sub-folder nerfkit can read (Blender / nerf_synthetic layout, multiscale, nerfstudio,
LLFF, COLMAP). Each scene trains into OUT/<scene>/ (a normal run folder) with the data's default
splits, is evaluated on its validation split, and leaves OUT/<scene>/benchmark.json, written last:

    finished scene    benchmark.json present          skipped on the next call
    interrupted scene checkpoints, no benchmark.json  resumed (--resume) with what is left of its budget
    new scene         nothing                          trained from scratch

A finished or interrupted scene is reused only when its settings (OUT/<scene>/benchmark_settings.json:
data folder, preset, budget, steps, eval stride, nerfkit version and commit) match the call's; otherwise
the call refuses, or with --overwrite trains that scene again. A scene that fails is a row marked failed
(with its error) and the command exits 1. The table of all scenes (PSNR, SSIM, steps, training time, and
the mean over the finished ones) is written as OUT/results.md, OUT/results.json and a bar plot
OUT/results.png. `jobs` > 1 runs that many scenes at
once, each in its own process (with its own GPU where there are several: CUDA_VISIBLE_DEVICES).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import jax
import numpy as np

from nerfkit.core.errors import ConfigError, DataError, NerfkitError
from nerfkit.core.outputs import replace_with
from nerfkit.core.presets import preset as make_preset
from nerfkit.core.presets import set_budget
from nerfkit.core.viz import read_jsonl
from nerfkit.data.loader import detect_format
from nerfkit.evaluation.evaluate import train_and_evaluate
from nerfkit.report.run import write_report_or_warn
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training.setup import clear_run, run_files

RESULT = "benchmark.json"


def find_scenes(root: Path) -> list[Path]:
    """The readable capture folders directly under root, sorted by name; NerfkitError if none."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: folder does not exist")
    try:
        detect_format(root)
        single = True
    except DataError:
        single = False
    if single:
        raise DataError(f"{root} is one scene; give the folder that holds the scene folders")
    scenes = []
    for p in sorted(root.iterdir()):
        try:
            if p.is_dir() and detect_format(p):
                scenes.append(p)
        except DataError:
            continue
    if not scenes:
        raise DataError(f"{root}: no scene folders in it (a scene holds transforms_train.json, metadata.json, "
                        f"transforms.json, poses_bounds.npy or sparse/0/)")
    return scenes


def _write_json(path: Path, data: dict) -> None:
    replace_with(path, lambda tmp: tmp.write_text(json.dumps(data, indent=2)))


SETTINGS = "benchmark_settings.json"


def nerfkit_version() -> str:
    """The installed nerfkit version, with the git commit of the source tree when it is a checkout."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version("nerfkit")
    except PackageNotFoundError:
        v = "unknown"
    src = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "-C", str(src), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                                text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return f"{v}+g{commit}" if commit else v


def scene_settings(scene: Path, preset: str, budget_minutes: float | None, max_steps: int | None,
                   eval_every: int, version: str) -> dict:
    """What a scene's result depends on: reused only when all of it matches."""
    return {"data_dir": str(Path(scene).resolve()), "preset": preset, "budget_minutes": budget_minutes,
            "max_steps": max_steps, "eval_every": eval_every, "nerfkit": version}


def _differences(old: dict, new: dict) -> str:
    return ", ".join(f"{k} {old.get(k)!r} -> {new[k]!r}" for k in new if old.get(k) != new[k])


def run_scene(scene: Path, run: Path, preset: str, budget_minutes: float | None, max_steps: int | None,
              eval_every: int, progress: bool, log: Callable[[str], None], overwrite: bool = False,
              version: str | None = None) -> dict:
    """Train (or resume) and evaluate one scene; returns its row. A finished or interrupted scene is reused
    only when its settings (scene_settings) match; otherwise ConfigError, or with `overwrite` it is trained
    again from scratch."""
    settings = scene_settings(scene, preset, budget_minutes, max_steps, eval_every, version or nerfkit_version())
    if run_files(run) or (run / RESULT).is_file():
        try:
            old = json.loads((run / SETTINGS).read_text())
        except (OSError, ValueError):
            old = {}
        if old != settings:
            why = _differences(old, settings) if old else f"no {SETTINGS}"
            if not overwrite:
                raise ConfigError(f"{run}: holds a result with other settings ({why}); pass --overwrite to train "
                                  f"{scene.name} again, or pick another --out")
            log(f"{scene.name}: earlier result has other settings ({why}); training it again (--overwrite)")
            clear_run(run)
            (run / RESULT).unlink(missing_ok=True)
    if (run / RESULT).is_file():
        log(f"{scene.name}: finished earlier with the same settings ({run / RESULT}); reused")
        return json.loads((run / RESULT).read_text())
    cfg = make_preset(preset)
    resume = bool(ckpt_lib.list_checkpoints(run / "checkpoints"))
    left = None
    if budget_minutes is not None:
        logged = read_jsonl(run / "metrics.jsonl") if resume else []
        spent = logged[-1]["elapsed"] / 60 if logged else 0.0
        left = max(budget_minutes - spent, 1e-3)
    set_budget(cfg, left, max_steps)
    log(f"{scene.name}: {'resuming' if resume else 'training'} ({preset}) into {run}")
    if not resume:
        clear_run(run)  # files of an attempt that died before its first checkpoint
    run.mkdir(parents=True, exist_ok=True)
    _write_json(run / SETTINGS, settings)
    res, run_cfg, ev = train_and_evaluate(scene, run, cfg, eval_every, progress, resume)
    write_report_or_warn(run)
    split = run_cfg.data.val_split
    rows = read_jsonl(run / "metrics.jsonl")
    row = {"scene": scene.name, "status": "finished", "data_dir": str(scene.resolve()), "preset": preset,
           "split": split, "every": eval_every, "n_views": ev["n_views"], "psnr": ev["psnr"], "ssim": ev["ssim"],
           "steps": res.step, "train_seconds": rows[-1]["elapsed"] if rows else None, "resumed": resume,
           "settings": settings}
    _write_json(run / RESULT, row)
    log(f"{scene.name}: {ev['psnr']:.2f} dB, SSIM {ev['ssim']:.4f} after {res.step} steps")
    return row


def failed_row(scene: Path, error: str) -> dict:
    return {"scene": scene.name, "status": "failed", "data_dir": str(scene.resolve()), "error": error}


def _gpu_count() -> int:
    return len([d for d in jax.devices() if d.platform == "gpu"])


def _run_jobs(root: Path, out: Path, names: list[str], argv: list[str], jobs: int, log) -> dict[str, str]:
    """Each scene in its own `nerfkit benchmark --only NAME` process, `jobs` at a time; returns {name: error}
    of the scenes whose process failed (the last line of its benchmark.log)."""
    gpus = _gpu_count()
    failed = {}

    def one(k_name):
        k, name = k_name
        env = dict(os.environ)
        if gpus > 1:
            env["CUDA_VISIBLE_DEVICES"] = str(k % jobs % gpus)
        (out / name).mkdir(parents=True, exist_ok=True)
        logfile = out / name / "benchmark.log"
        with open(logfile, "a") as f:
            code = subprocess.call([sys.executable, "-m", "nerfkit", "benchmark", str(root), "--out", str(out),
                                    "--only", name, "--jobs", "1", "--no-progress"] + argv, stdout=f, stderr=f,
                                   env=env)
        if code == 0:
            log(f"{name}: done")
        else:
            lines = [x for x in logfile.read_text(errors="replace").splitlines() if x.strip()]
            failed[name] = f"exit {code}: {lines[-1].strip() if lines else 'no output'} (see {logfile})"
            log(f"{name}: failed ({failed[name]})")

    with ThreadPoolExecutor(jobs) as pool:
        list(pool.map(one, enumerate(names)))
    return failed


def write_table(out: Path, rows: list[dict], preset: str, budget_text: str) -> dict:
    """results.json, results.md and the bar plot results.png of all rows; the mean is over the finished
    scenes, and says so when some failed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    done = [r for r in rows if r.get("status", "finished") == "finished"]
    failed = [r["scene"] for r in rows if r not in done]
    mean = {k: float(np.mean([r[k] for r in done])) if done else None for k in ("psnr", "ssim")}
    mean["scenes"] = len(done)
    table = {"preset": preset, "budget": budget_text, "scenes": rows, "mean": mean, "failed": failed}
    _write_json(out / "results.json", table)
    lines = [f"# nerfkit benchmark: preset `{preset}`, {budget_text} per scene", "",
             "| scene | split | views | PSNR (dB) | SSIM | steps | train time (s) |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        if r not in done:
            lines.append(f"| {r['scene']} | **failed**: {r['error']} | | | | | |")
            continue
        t = "-" if r["train_seconds"] is None else f"{r['train_seconds']:.0f}"
        lines.append(f"| {r['scene']} | `{r['split']}` | {r['n_views']} | {r['psnr']:.2f} | {r['ssim']:.4f} | "
                     f"{r['steps']} | {t} |")
    label = "**mean**" if not failed else f"**mean of {len(done)} of {len(rows)} scenes** ({len(failed)} failed)"
    if done:
        lines += [f"| {label} | | | **{mean['psnr']:.2f}** | **{mean['ssim']:.4f}** | | |", ""]
    (out / "results.md").write_text("\n".join(lines))
    fig, ax = plt.subplots(figsize=(max(4.0, 1.0 + 0.9 * len(rows)), 3.2), dpi=100)
    ax.bar([r["scene"] for r in rows], [r.get("psnr", 0.0) if r in done else 0.0 for r in rows], color="#4c72b0")
    if done:
        ax.axhline(mean["psnr"], color="#c44e52", ls="--", label=f"mean {mean['psnr']:.2f} dB"
                   + (f" ({len(done)} of {len(rows)})" if failed else ""))
        ax.legend(fontsize=8, loc="lower right")
    for k, r in enumerate(rows):
        ax.text(k, r["psnr"] if r in done else 0.0, f"{r['psnr']:.2f}" if r in done else "failed", ha="center",
                va="bottom", fontsize=8)
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(f"preset {preset}, {budget_text}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "results.png")
    plt.close(fig)
    return table


def benchmark(root: str | Path, out: str | Path, preset: str = "ngp", budget_minutes: float | None = None,
              max_steps: int | None = None, jobs: int = 1, only: str | None = None, eval_every: int = 1,
              progress: bool = True, log: Callable[[str], None] = print, overwrite: bool = False) -> dict:
    """Train and evaluate every scene under root (see the module docstring); returns the table, whose
    "failed" lists the scenes that failed (each a row with its error)."""
    root, out = Path(root), Path(out)
    make_preset(preset)  # unknown preset: ConfigError now, not after the first scene
    if budget_minutes is None and max_steps is None:
        raise ConfigError("give each scene a budget: --budget-minutes M (and/or --max-steps N)")
    if budget_minutes is not None and not budget_minutes > 0:
        raise ConfigError(f"--budget-minutes must be positive (got {budget_minutes})")
    for flag, v in (("--max-steps", max_steps), ("--jobs", jobs), ("--eval-every", eval_every)):
        if v is not None and v < 1:
            raise ConfigError(f"{flag} must be >= 1 (got {v})")
    scenes = find_scenes(root)
    if only is not None:
        scenes = [s for s in scenes if s.name == only]
        if not scenes:
            raise DataError(f"--only {only}: no such scene folder under {root}")
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: is a file; name a folder")
    if out.resolve() == Path(root).resolve():
        raise ConfigError(f"--out {out}: is the folder of scenes itself; name a folder beside it for the results")
    version = nerfkit_version()
    budget_text = " or ".join(([f"{budget_minutes:g} min"] if budget_minutes is not None else [])
                              + ([f"{max_steps} steps"] if max_steps is not None else []))
    log(f"benchmark of {len(scenes)} scene(s) under {root} ({', '.join(s.name for s in scenes)}): preset {preset}, "
        f"{budget_text} each, {jobs} at a time; writing {out}")
    out.mkdir(parents=True, exist_ok=True)
    job_errors = {}
    todo = [s for s in scenes if not (out / s.name / RESULT).is_file()]
    if jobs > 1 and len(todo) > 1:
        argv = ["--preset", preset, "--eval-every", str(eval_every)] + (["--overwrite"] if overwrite else [])
        argv += ["--budget-minutes", str(budget_minutes)] if budget_minutes is not None else []
        argv += ["--max-steps", str(max_steps)] if max_steps is not None else []
        job_errors = _run_jobs(root, out, [s.name for s in todo], argv, jobs, log)
    rows = []
    for s in scenes:
        if s.name in job_errors:
            rows.append(failed_row(s, job_errors[s.name]))
            continue
        try:
            rows.append(run_scene(s, out / s.name, preset, budget_minutes, max_steps, eval_every, progress, log,
                                  overwrite, version))
        except NerfkitError as e:
            if only is not None:
                raise
            log(f"{s.name}: failed: {e}")
            rows.append(failed_row(s, str(e)))
    if only is not None:  # one scene of a --jobs run: the parent writes the table
        return {"scenes": rows, "failed": []}
    table = write_table(out, rows, preset, budget_text)
    m = table["mean"]
    if m["scenes"]:
        log(f"mean over {m['scenes']} of {len(rows)} scene(s): {m['psnr']:.2f} dB, SSIM {m['ssim']:.4f}; "
            f"{out / 'results.md'}, {out / 'results.png'}")
    return table
