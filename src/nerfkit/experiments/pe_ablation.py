"""Experiments: several runs that differ in one setting, trained under one budget, and
compared in one folder (results table, overlaid curves, image grids, videos, HTML report).

`pe_ablation` answers the reference report's question "what does positional encoding
buy?" with three models that share the preset, the seed and the budget:

    Model-1  PE, L_xyz=10, L_dir=4   (the report's model)
    Model-2  no PE (raw x and d into the MLP)
    Model-3  PE, L_xyz=5, L_dir=2    (fewer frequencies)

Experiment folder:

    OUT/model1_pe/, model2_no_pe/, model3_pe_l5/   run folders (+ eval_<val split>/, renders/orbitN_WxH/, report.html)
    OUT/results.json, results.md                   val PSNR and SSIM per model
    OUT/plots/{loss,train_psnr,val_psnr}_vs_{step,time}.png
    OUT/grid_view_K.png                            GT | each model's render, and its depth map, per val view
    OUT/report.html                                everything above on one page
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from imageio.v3 import imread

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError
from nerfkit.core.presets import PRESETS
from nerfkit.core.presets import preset as make_preset
from nerfkit.core.viz import read_jsonl
from nerfkit.data.loader import load_scene
from nerfkit.evaluation.evaluate import render_run, split_slug, train_and_evaluate
from nerfkit.experiments.common import (
    apply_settings,
    budget_record,
    check_at_least_one,
    check_budget,
    gt_depth,
    image_grid,
    num_text,
    overlay_plots,
    refuse_taken,
    write_results,
)
from nerfkit.experiments.report import write_experiment_report
from nerfkit.report.run import write_report
from nerfkit.run.folder import RunFolder
from nerfkit.training.validation import evenly_spaced


@dataclass(frozen=True)
class Variant:
    run_dir: str
    label: str
    description: str
    pe: bool
    l_xyz: int | None = None  # None: keep the preset's value (unused without PE)
    l_dir: int | None = None


PE_ABLATION = (
    Variant("model1_pe", "Model-1", "PE, L_xyz=10, L_dir=4", True, 10, 4),
    Variant("model2_no_pe", "Model-2", "no PE (raw x, d)", False),
    Variant("model3_pe_l5", "Model-3", "PE, L_xyz=5, L_dir=2", True, 5, 2),
)

PE_QUESTION = (
    "Does positional encoding matter, and how many frequencies does it need? Three models share the preset, "
    "the seed and the training budget and differ only in how positions x and view directions d are fed to "
    "the MLP: Model-1 uses the encoding gamma(p) = (sin(2^k pi p), cos(2^k pi p)), k < L, with L_xyz=10 and "
    "L_dir=4; Model-2 feeds raw coordinates; Model-3 uses fewer frequencies, L_xyz=5 and L_dir=2."
)


def _markdown(results: dict) -> str:
    ev, b = results["eval"], results["budget"]
    lines = [
        f"# {results['title']}",
        "",
        f"Data: `{results['data_dir']}`. Preset `{results['preset']}`, seed {results['seed']}, the same budget per "
        f"model: {b['text']}. Validation metrics on `{ev['split']}`, every {ev['every']} view(s) "
        f"({ev['n_views']} views).",
        "",
        "| model | encoding | steps | train time (s) | val PSNR (dB) | val SSIM |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for m in results["models"]:
        lines.append(f"| {m['label']} | {m['description']} | {m['steps']} | {num_text(m['train_seconds'], 0)} | "
                     f"{m['psnr']:.2f} | {m['ssim']:.4f} |")
    lines += ["", "Run folders: " + ", ".join(f"`{m['run_dir']}/`" for m in results["models"])
              + ". Curves in `plots/`, image grids `grid_view_K.png`, everything on one page in `report.html`.", ""]
    return "\n".join(lines)


def pe_ablation(data_dir: str | Path, out: str | Path, preset: str = "seed", budget_minutes: float | None = None,
                max_steps: int | None = None, seed: int | None = None, eval_every: int = 2, orbit_frames: int = 40,
                grid_views: int = 2, val_every: int | None = None, progress: bool = True,
                log: Callable[[str], None] = print, train_split: str | None = None, val_split: str | None = None,
                target_width: int | None = None, downscale: int | None = None) -> dict:
    """Train Model-1 (PE 10/4), Model-2 (no PE) and Model-3 (PE 5/2) from `preset` with the
    same seed and budget (`budget_minutes` of wall time and/or `max_steps` steps, per model),
    evaluate each on its val split (every `eval_every`-th view), render an `orbit_frames`
    orbit of each at the training resolution, and write results.{json,md}, the overlaid
    plots, `grid_views` image grids and report.html into `out`. Returns the results dict.
    train_split, val_split, target_width, downscale: the data settings (default: the data's)."""
    data_dir, out = Path(data_dir), Path(out)
    check_budget(budget_minutes, max_steps)
    check_at_least_one((("--eval-every", eval_every), ("--orbit-frames", orbit_frames), ("--grid-views", grid_views)))
    refuse_taken(out, [v.run_dir for v in PE_ABLATION])
    check_mlp_preset(preset)
    cfgs = [variant_config(v, preset, budget_minutes, max_steps, seed, val_every, train_split, val_split,
                           target_width, downscale) for v in PE_ABLATION]
    budget = budget_record(budget_minutes, max_steps)
    log(f"PE ablation on {data_dir}: 3 models, preset {preset}, {budget['text']} each; writing {out}")

    models = []
    for k, (v, cfg) in enumerate(zip(PE_ABLATION, cfgs), 1):
        row, val_split = _train_variant(k, v, cfg, data_dir, out, eval_every, orbit_frames, progress, log)
        models.append(row)

    log("writing the results table, curves, image grids and report")
    ev0 = json.loads((out / models[0]["eval_json"]).read_text())
    plots = overlay_plots(out, [m["label"] for m in models], [out / m["run_dir"] for m in models])
    grids = _grids(data_dir, out, models, val_split, [v["view"] for v in ev0["per_view"]], grid_views)
    results = {
        "experiment": "pe-ablation", "title": "PE ablation: what positional encoding buys",
        "subtitle": f"{data_dir.resolve().name} · preset {preset} · {budget['text']} per model",
        "question": PE_QUESTION,
        "data_dir": str(data_dir.resolve()), "preset": preset, "seed": cfgs[0].train.seed, "budget": budget,
        "eval": {"split": val_split, "every": eval_every, "n_views": ev0["n_views"]},
        "orbit_frames": orbit_frames, "models": models, "plots": plots, "grids": grids,
    }
    write_results(out, results, _markdown(results))
    report = write_experiment_report(out, results)
    log(f"done: {out / 'results.md'}, {report}")
    return results


def check_mlp_preset(preset: str) -> None:
    """ConfigError unless `preset`'s method reads --pe (the MLP field: the only positional encoding to ablate)."""
    from nerfkit.models.registry import method_class

    def ablates(p: str) -> bool:
        return "field.pe" in method_class(make_preset(p)).reads

    if not ablates(preset):
        mlp = [p for p in PRESETS if ablates(p)]
        raise ConfigError(f"pe-ablation compares positional encodings of the MLP field; preset {preset!r} uses the "
                          f"{make_preset(preset).field.kind!r} field. Pick an MLP preset ({', '.join(mlp)}).")


def variant_config(v: Variant, preset: str, budget_minutes: float | None, max_steps: int | None, seed: int | None,
                   val_every: int | None, train_split: str | None, val_split: str | None, target_width: int | None,
                   downscale: int | None) -> Config:
    """The config of variant v: `preset` with v's encoding (pe, and L_xyz / L_dir where v sets them), the
    experiment's shared settings (common.apply_settings) and the data size."""
    cfg = make_preset(preset)
    cfg.field.pe = v.pe
    if v.l_xyz is not None:
        cfg.field.l_xyz = v.l_xyz
    if v.l_dir is not None:
        cfg.field.l_dir = v.l_dir
    apply_settings(cfg, budget_minutes, max_steps, seed, val_every, train_split, val_split)
    cfg.data.target_width, cfg.data.downscale = target_width, downscale
    return cfg


def _train_variant(k: int, v: Variant, cfg: Config, data_dir: Path, out: Path, eval_every: int, orbit_frames: int,
                   progress: bool, log: Callable[[str], None]) -> tuple[dict, str]:
    """Train variant v (the k-th of 3) into OUT/<run_dir>, evaluate it, render its orbit and write its run
    report. Returns (its row of results["models"], the split it validated on)."""
    run = out / v.run_dir
    log(f"[{k}/3] {v.label} ({v.description}): training into {run}, then evaluating (every {eval_every} "
        f"view(s) of its val split)")
    res, run_cfg, ev = train_and_evaluate(data_dir, run, cfg, eval_every, progress)
    val_split = run_cfg.data.val_split  # the split the run validated on (data default or given)
    log(f"[{k}/3] {v.label}: step {res.step}, val PSNR {ev['psnr']:.2f} dB, SSIM {ev['ssim']:.4f}; "
        f"rendering a {orbit_frames}-frame orbit")
    info = render_run(run, data_dir, orbit=orbit_frames, progress=progress)
    write_report(run)
    return _model_row(v, cfg, res, ev, info, out, val_split), val_split


def _model_row(v: Variant, cfg: Config, res, ev: dict, info: dict, out: Path, val_split: str) -> dict:
    """One model's row of results["models"]: its encoding, steps and time, the last logged training and
    validation metrics, the evaluation (res: TrainResult, ev: evaluate_run's, info: render_run's)."""
    run = out / v.run_dir
    rows, vrows = read_jsonl(run / "metrics.jsonl"), read_jsonl(run / "val_metrics.jsonl")
    vid = Path(info["out"])
    return {
        "label": v.label, "description": v.description, "run_dir": v.run_dir,
        "pe": cfg.field.pe, "l_xyz": cfg.field.l_xyz if cfg.field.pe else None,
        "l_dir": cfg.field.l_dir if cfg.field.pe else None,
        "steps": res.step, "train_seconds": rows[-1]["elapsed"] if rows else None,
        "steps_per_second": round(res.steps_per_second, 3),
        "final_train_loss": rows[-1]["loss"] if rows else None,
        "final_train_psnr": rows[-1]["psnr"] if rows else None,
        "val_psnr_training": vrows[-1]["psnr"] if vrows else None,
        "psnr": ev["psnr"], "ssim": ev["ssim"], "eval_json": f"{v.run_dir}/eval_{split_slug(val_split)}.json",
        "orbit_video": (vid / "rgb.mp4").relative_to(out).as_posix(),
        "depth_video": (vid / "depth.mp4").relative_to(out).as_posix(),
        "video_width": info["width"],
    }


def _grids(data_dir: Path, out: Path, models: list[dict], val_split: str, ids: list[int], grid_views: int) -> list:
    """OUT/grid_view_K.png for `grid_views` evenly spaced views of the evaluated ids (image_grid: ground truth,
    then each model's render, its depth below); returns [{"view", "name", "path"}]."""
    d = RunFolder(out / models[0]["run_dir"]).config().data
    val = load_scene(data_dir, val_split, format=d.format, downscale=d.downscale, target_width=d.target_width,
                     background=d.background, masks=d.masks, holdout_every=d.holdout_every)
    bg = (1.0, 1.0, 1.0) if d.background == "white" else (0.0, 0.0, 0.0)
    grids = []
    for j in evenly_spaced(len(ids), grid_views):
        k = ids[j]
        renders, depths, titles = [], [], []
        for m in models:
            rdir = out / m["run_dir"] / f"eval_{split_slug(val_split)}"
            renders.append(imread(rdir / f"view_{k:03d}_rgb.png")[..., :3] / 255.0)
            depths.append(imread(rdir / f"view_{k:03d}_depth.png")[..., :3] / 255.0)
            pv = next(p for p in json.loads((out / m["eval_json"]).read_text())["per_view"] if p["view"] == k)
            titles.append(f"{m['label']}\n{m['description']}\n{pv['psnr']:.2f} dB, SSIM {pv['ssim']:.3f}")
        rel = f"grid_view_{k:03d}.png"
        image_grid(out / rel, val.images[k], renders, depths, titles, gt_depth(data_dir, val.names[k]), bg)
        grids.append({"view": k, "name": val.names[k], "path": rel})
    return grids
