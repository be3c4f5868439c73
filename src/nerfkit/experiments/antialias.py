"""Anti-aliasing on multiscale data, measured as mip-NeRF measures it (Barron et al. 2021, sec. 5.1).

Four models share the seed, the splits and one wall-clock budget each, and train on every scale of a
multiscale capture (`nerfkit make-multiscale`: each image at full, 1/2, 1/4, 1/8 resolution, loss
weighted by pixel area):

    nerf            thin rays, positional encoding (two MLPs, coarse + fine)
    mipnerf         cones, integrated positional encoding of conical frustums (one MLP, coarse + resampled fine)
    ngp             hash grid + occupancy grid, thin rays
    ngp_antialias   the same with hash-grid levels finer than the pixel footprint down-weighted (--antialias)

The MLP models run at the papers' sizes (`mlp_size="paper"`: D=8, W=256, NeRF 64 + 128 samples,
mip-NeRF 128 + 128) or, for CPUs, both at the reference report's size (`"small"`: D=4, W=128, 64 + 64).
Each model is evaluated at every scale of the validation split (PSNR / SSIM per scale and their mean).

Experiment folder:

    OUT/<model>/                      run folders (+ eval_<split>_multiscale/d<level>/, report.html)
    OUT/results.json, results.md      PSNR / SSIM per scale and mean, steps, time per model
    OUT/plots/*.png                   overlaid training curves
    OUT/scales_view_K.png             ground truth and each model at every scale (nearest-neighbour enlarged)
    OUT/crops_view_K.png              the same, cropped where the ground truth has the most fine detail
    OUT/report.html                   everything above on one page
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from imageio.v3 import imread

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.presets import preset as make_preset
from nerfkit.core.viz import read_jsonl
from nerfkit.data.formats.multiscale import level_specs
from nerfkit.data.loader import load_scene, read_capture
from nerfkit.evaluation.evaluate import split_slug, train_and_evaluate
from nerfkit.experiments.common import (
    apply_settings,
    budget_record,
    check_at_least_one,
    check_budget,
    labelled_grid,
    overlay_plots,
    refuse_taken,
    write_results,
)
from nerfkit.report import html as h
from nerfkit.report.run import write_report
from nerfkit.training.validation import evenly_spaced

MLP_SIZES = ("small", "paper")


@dataclass(frozen=True)
class AAModel:
    run_dir: str
    label: str
    description: str
    preset: str
    antialias: bool = False


ANTIALIAS_MODELS = (
    AAModel("nerf", "NeRF", "thin rays, positional encoding", "nerf"),
    AAModel("mipnerf", "mip-NeRF", "cones, integrated positional encoding", "mipnerf"),
    AAModel("ngp", "NGP", "hash grid, thin rays", "ngp"),
    AAModel("ngp_antialias", "NGP --antialias", "hash grid, levels finer than the footprint down-weighted", "ngp",
            antialias=True),
)
PAIRS = (("nerf", "mipnerf"), ("ngp", "ngp_antialias"))

QUESTION = (
    "Does casting cones instead of rays remove the blur and aliasing of a model that sees a scene at several "
    "resolutions? Every model trains on all four scales of the same images (full, 1/2, 1/4, 1/8; loss weighted by "
    "pixel area) for the same wall-clock time, and is scored at each scale. mip-NeRF replaces NeRF's positional "
    "encoding of points with the integrated encoding of conical frustums; NGP --antialias fades out the hash-grid "
    "levels finer than each sample's pixel footprint."
)


def model_config(m: AAModel, mlp_size: str, budget_minutes: float | None, max_steps: int | None, seed: int | None,
                 train_split: str | None, val_split: str | None, val_every: int | None) -> Config:
    """The config of one model of the experiment (see the module docstring)."""
    cfg = make_preset(m.preset)
    if m.preset in ("nerf", "mipnerf") and mlp_size == "small":
        cfg.field.depth, cfg.field.width = 4, 128
        cfg.sampler.n_samples, cfg.sampler.n_importance = 64, 64
        cfg.train.precrop_steps = 0
    cfg.field.antialias = m.antialias
    return apply_settings(cfg, budget_minutes, max_steps, seed, val_every, train_split, val_split)


def detail_window(img: np.ndarray, frac: float = 0.25) -> tuple[float, float, float]:
    """(top, left, side) as fractions of the image: the square window of side frac that holds the most
    fine detail of img [H, W, 3] (sum of |discrete Laplacian| of the luminance), on a stride of frac / 4."""
    g = np.asarray(img, np.float64)[..., :3].mean(-1)
    lap = np.abs(4 * g[1:-1, 1:-1] - g[:-2, 1:-1] - g[2:, 1:-1] - g[1:-1, :-2] - g[1:-1, 2:])
    lap = np.pad(lap, 1)
    h, w = g.shape
    s = max(2, int(round(frac * min(h, w))))
    stride = max(1, s // 4)
    cs = np.pad(lap.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    best, where = -1.0, (0, 0)
    for i in range(0, h - s + 1, stride):
        for j in range(0, w - s + 1, stride):
            e = cs[i + s, j + s] - cs[i, j + s] - cs[i + s, j] + cs[i, j]
            if e > best:
                best, where = e, (i, j)
    return where[0] / h, where[1] / w, s / min(h, w)


def crop(img: np.ndarray, window: tuple[float, float, float]) -> np.ndarray:
    """The window (fractions, detail_window) of img [H, W, C], at least 1 pixel."""
    h, w = img.shape[:2]
    top, left, side = window
    i, j = int(round(top * h)), int(round(left * w))
    s = max(1, int(round(side * min(h, w))))
    return img[i:i + s, j:j + s]


def _markdown(results: dict) -> str:
    b, ev = results["budget"], results["eval"]
    widths = [s["width"] for s in results["models"][0]["scales"]]
    lines = [f"# {results['title']}", "",
             f"Data: `{results['data_dir']}`; every model trains on all scales of `{results['train_split']}` for "
             f"{b['text']} (seed {results['seed']}, MLP size `{results['mlp_size']}`), and is scored on "
             f"`{ev['split']}`, every {ev['every']} view(s) at each scale.", "",
             "| model | " + " | ".join(f"{w} px" for w in widths) + " | mean PSNR | mean SSIM | steps |",
             "| --- | " + " | ".join("---:" for _ in widths) + " | ---: | ---: | ---: |"]
    for m in results["models"]:
        lines.append(f"| {m['label']} | " + " | ".join(f"{s['psnr']:.2f}" for s in m["scales"])
                     + f" | {m['psnr']:.2f} | {m['ssim']:.4f} | {m['steps']} |")
    lines += ["", "PSNR in dB. " + " ".join(results["verdicts"]), ""]
    return "\n".join(lines)


def verdicts(models: list[dict]) -> list[str]:
    """One sentence per pair of the experiment that ran (the done-when comparisons of issue 12)."""
    by = {m["run_dir"]: m for m in models}
    out = []
    if "nerf" in by and "mipnerf" in by:
        a, b = by["nerf"], by["mipnerf"]
        out.append(f"mip-NeRF {'beats' if b['psnr'] > a['psnr'] else 'does not beat'} NeRF on the mean over scales "
                   f"({b['psnr']:.2f} vs {a['psnr']:.2f} dB).")
    if "ngp" in by and "ngp_antialias" in by:
        a, b = by["ngp"], by["ngp_antialias"]
        parts = [f"{sb['width']} px {sb['psnr'] - sa['psnr']:+.2f} dB" for sa, sb in zip(a["scales"], b["scales"])]
        out.append(f"NGP --antialias against NGP: {', '.join(parts)}; mean {b['psnr'] - a['psnr']:+.2f} dB.")
    return out


def antialias_experiment(data_dir: str | Path, out: str | Path, budget_minutes: float | None = None,
                         max_steps: int | None = None, models: list[str] | None = None, mlp_size: str = "small",
                         seed: int | None = None, eval_every: int = 5, grid_views: int = 1,
                         val_every: int | None = None, train_split: str | None = None, val_split: str | None = None,
                         progress: bool = True, log: Callable[[str], None] = print) -> dict:
    """Train the chosen models (default all four) on every scale of the multiscale capture `data_dir` for
    `budget_minutes` of wall time and/or `max_steps` steps each (whichever comes first), evaluate each at
    every scale of the val split (every `eval_every`-th view), and write results.{json,md}, curves,
    per-scale grids and crops of `grid_views` views and report.html into `out`. Returns the results dict."""
    data_dir, out = Path(data_dir), Path(out)
    check_budget(budget_minutes, max_steps)
    if mlp_size not in MLP_SIZES:
        raise ConfigError(f"--mlp-size must be one of {', '.join(MLP_SIZES)} (got {mlp_size!r})")
    check_at_least_one((("--eval-every", eval_every), ("--grid-views", grid_views)))
    chosen = chosen_models(models)
    specs = [m for m in ANTIALIAS_MODELS if m.run_dir in chosen]
    if not read_capture(data_dir, train_split or "train").levels:
        raise NerfkitError(f"{data_dir}: not multiscale data (no metadata.json); make it first with "
                           f"nerfkit make-multiscale {data_dir} --out {data_dir}_ms")
    refuse_taken(out, [m.run_dir for m in specs])
    cfgs = [model_config(m, mlp_size, budget_minutes, max_steps, seed, train_split, val_split, val_every)
            for m in specs]
    budget = budget_record(budget_minutes, max_steps)
    log(f"anti-aliasing on {data_dir}: {len(specs)} models ({', '.join(chosen)}), {budget['text']} each; writing {out}")

    rows = []
    for k, (m, cfg) in enumerate(zip(specs, cfgs), 1):
        row, rc = _train_model(f"[{k}/{len(specs)}]", m, cfg, data_dir, out, eval_every, progress, log)
        rows.append(row)
        val_split, train_split = rc.data.val_split, rc.data.train_split

    log("writing the results table, curves, per-scale grids and report")
    plots = overlay_plots(out, [m["label"] for m in rows], [out / m["run_dir"] for m in rows])
    first = json.loads((out / rows[0]["eval_json"]).read_text())
    ids = sorted({v["view"] for v in first["per_view"]})
    grids = scale_grids(data_dir, out, rows, val_split, cfgs[0].data.background, [ids[j] for j in
                                                                                  evenly_spaced(len(ids), grid_views)])
    results = {
        "experiment": "antialias", "title": "Anti-aliasing: rays vs cones on multiscale data",
        "subtitle": f"{data_dir.resolve().name} · {budget['text']} per model · MLP size {mlp_size}",
        "question": QUESTION, "data_dir": str(data_dir.resolve()), "train_split": train_split,
        "seed": cfgs[0].train.seed, "mlp_size": mlp_size, "budget": budget,
        "eval": {"split": val_split, "every": eval_every, "n_views": first["n_views"]},
        "models": rows, "verdicts": verdicts(rows), "plots": plots, "grids": grids,
    }
    write_results(out, results, _markdown(results))
    report = write_antialias_report(out, results)
    log(f"done: {out / 'results.md'}, {report}")
    return results


def chosen_models(models: list[str] | None) -> list[str]:
    """The run_dirs of ANTIALIAS_MODELS that --models names, in its order without repeats (None or empty: all);
    ConfigError naming any unknown one."""
    known = [m.run_dir for m in ANTIALIAS_MODELS]
    chosen = known if not models else list(dict.fromkeys(models))
    bad = [m for m in chosen if m not in known]
    if bad:
        raise ConfigError(f"--models: unknown model(s) {', '.join(bad)}; choose from {', '.join(known)}")
    return chosen


def _train_model(tag: str, m: AAModel, cfg: Config, data_dir: Path, out: Path, eval_every: int, progress: bool,
                 log: Callable[[str], None]) -> tuple[dict, Config]:
    """Train model m into OUT/<run_dir>, evaluate it at every scale and write its run report (tag: "[k/n]" in
    the log lines). Returns (its row of results["models"], the run's resolved config)."""
    run = out / m.run_dir
    log(f"{tag} {m.label} ({m.description}): training into {run}, then evaluating every scale")
    res, rc, ev = train_and_evaluate(data_dir, run, cfg, eval_every, progress)
    write_report(run)
    metrics = read_jsonl(run / "metrics.jsonl")
    per_scale = ", ".join(f"{s['width']} px {s['psnr']:.2f}" for s in ev["scales"])
    log(f"{tag} {m.label}: step {res.step}; {per_scale}; mean {ev['psnr']:.2f} dB")
    row = {"label": m.label, "description": m.description, "run_dir": m.run_dir, "preset": m.preset,
           "antialias": m.antialias, "depth": rc.field.depth, "width": rc.field.width,
           "samples": [rc.sampler.n_samples, rc.sampler.n_importance], "steps": res.step,
           "train_seconds": metrics[-1]["elapsed"] if metrics else None,
           "psnr": ev["psnr"], "ssim": ev["ssim"],
           "scales": [{k2: s[k2] for k2 in ("level", "width", "height", "psnr", "ssim", "n_views")}
                      for s in ev["scales"]],
           "eval_json": Path(ev["written"]).relative_to(out).as_posix()}
    return row, rc


def scale_grids(data_dir: Path, out: Path, rows: list[dict], val_split: str, background: str,
                views: list[int]) -> list[dict]:
    """OUT/scales_view_K.png and OUT/crops_view_K.png of each view K in views: a row per scale of the val split
    (ground truth, then each model's render; the crop: detail_window of the full-size ground truth), each
    render's PSNR under it. Returns [{"view", "name", "scales", "crops", "window"}]."""
    levels = level_specs(read_capture(data_dir, val_split), val_split)
    slug = split_slug(val_split) + "_multiscale"
    gts = [load_scene(data_dir, spec, background=background) for _, spec in levels]
    psnrs = {m["run_dir"]: {(p["level"], p["view"]): p["psnr"]
                            for p in json.loads((out / m["eval_json"]).read_text())["per_view"]} for m in rows}
    cols = ["ground truth"] + [m["label"] for m in rows]
    grids = []
    for k in views:
        window = detail_window(gts[0].images[k])
        full, crops, labels = [], [], []
        for (lvl, _), gt in zip(levels, gts):
            imgs = [gt.images[k]] + [imread(out / m["run_dir"] / f"eval_{slug}" / f"d{lvl}" / f"view_{k:03d}_rgb.png")
                                     [..., :3] / 255.0 for m in rows]
            full.append(imgs)
            crops.append([crop(im, window) for im in imgs])
            labels.append(f"{gt.width} px")
        notes = [[""] + [f"{psnrs[m['run_dir']][(lvl, k)]:.2f} dB" for m in rows] for lvl, _ in levels]
        labelled_grid(out / f"scales_view_{k:03d}.png", full, labels, cols, notes, cell_px=200)
        labelled_grid(out / f"crops_view_{k:03d}.png", crops, labels, cols, notes, cell_px=160)
        grids.append({"view": k, "name": gts[0].names[k], "scales": f"scales_view_{k:03d}.png",
                      "crops": f"crops_view_{k:03d}.png", "window": list(window)})
    return grids


def write_antialias_report(exp: Path, results: dict) -> Path:
    """EXP/report.html: the question, the per-scale table, the verdicts, the curves, the per-scale grids and
    crops, and links to each model's run report."""

    models = results["models"]
    widths = [s["width"] for s in models[0]["scales"]]
    best = [max(m["scales"][i]["psnr"] for m in models) for i in range(len(widths))] + [max(m["psnr"] for m in models)]
    rows = []
    for m in models:
        rep = exp / m["run_dir"] / "report.html"
        name = h.e(m["label"]) + (f" ({h.link(rep, exp, 'run report')})" if rep.is_file() else "")
        vals = [s["psnr"] for s in m["scales"]] + [m["psnr"]]
        cells = [f"<b>{h.fmt(v)}</b>" if v == b else h.fmt(v) for v, b in zip(vals, best)]
        rows.append([name, h.e(m["description"]), h.e(f"D={m['depth']} W={m['width']}, {m['samples'][0]} + "
                                                     f"{m['samples'][1]}" if m["preset"] != "ngp" else "hash grid"),
                     h.e(m["steps"]), h.e(h.minutes(m["train_seconds"]))] + cells + [h.fmt(m["ssim"], 4)])
    ev, b = results["eval"], results["budget"]
    setup = h.table(["", ""], [
        ["data", h.e(results["data_dir"])], ["training", h.e(f"every scale of {results['train_split']}")],
        ["budget per model", h.e(b["text"])], ["seed", h.e(results["seed"])],
        ["evaluation", h.e(f"{ev['split']} at every scale, every {ev['every']} view(s): {ev['n_views']} renders")],
        ["files", " ".join(h.link(exp / n, exp) for n in ("results.md", "results.json") if (exp / n).is_file())]])
    head = ["model", "rays", "MLP", "steps", "train time"] + [f"{w} px" for w in widths] + ["mean PSNR", "mean SSIM"]
    n = len(head)
    table = h.table(head, rows, numeric=set(range(3, n)))
    verdict = "".join(f"<p>{h.e(v)}</p>" for v in results["verdicts"])
    res_html = (f"<p>{h.e(results['question'])}</p>" + setup + table + verdict
                + '<p class="note">PSNR in dB per scale (bold: the best at that scale).</p>')
    figs = [h.img(exp / p, exp, k, h.e(k.replace("_", " "))) for k, p in results["plots"].items() if (exp / p).is_file()]
    curves = f'<div class="plots two">{"".join(figs)}</div>' if figs else ""
    gfigs = []
    for g in results["grids"]:
        for key, what in (("scales", "every scale, enlarged to the same size"),
                          ("crops", "the crop with the most fine detail, at every scale")):
            if (exp / g[key]).is_file():
                gfigs.append(h.img(exp / g[key], exp, f"{key} of view {g['view']}",
                                  h.e(f"val view {g['view']} ({g['name']}): {what}; PSNR of the whole view")))
    grids = f'<div class="gallery">{"".join(gfigs)}</div>' if gfigs else ""
    sections = [("results", "Results", res_html), ("views", "Views at every scale", grids),
                ("curves", "Curves", curves)]
    return h.write(exp / "report.html", h.page(results["title"], results["subtitle"], sections))
