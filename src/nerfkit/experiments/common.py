"""What the experiments share: the argument checks, the budget sentence, the results files, overlaid curves
of several runs, and labelled image grids (ground truth, then each model's render; depth maps below)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.presets import set_budget
from nerfkit.core.viz import colorize_depth, depth_range, plot_curves, read_jsonl
from nerfkit.data.formats.registry import holds_capture
from nerfkit.training import checkpoint as ckpt_lib


def budget_text(budget_minutes: float | None, max_steps: int | None) -> str:
    parts = []
    if budget_minutes is not None:
        parts.append(f"{budget_minutes:g} min of wall time (compile and validation included)")
    if max_steps is not None:
        parts.append(f"{max_steps} steps")
    return " or ".join(parts) + (", whichever comes first" if len(parts) == 2 else "")


def check_budget(budget_minutes: float | None, max_steps: int | None) -> None:
    """ConfigError unless a budget is given and positive."""
    if budget_minutes is None and max_steps is None:
        raise ConfigError("give the models a budget: --budget-minutes M and/or --max-steps N")
    if budget_minutes is not None and not budget_minutes > 0:
        raise ConfigError(f"--budget-minutes must be positive (got {budget_minutes})")
    if max_steps is not None and max_steps < 1:
        raise ConfigError(f"--max-steps must be >= 1 (got {max_steps})")


def check_at_least_one(counts: tuple[tuple[str, int], ...]) -> None:
    """ConfigError naming the first (flag, value) of counts whose value is below 1."""
    for name, v in counts:
        if v < 1:
            raise ConfigError(f"{name} must be >= 1 (got {v})")


def refuse_taken(out: Path, run_dirs: list[str]) -> None:
    """NerfkitError when out already holds a checkpointed run in any of run_dirs (an experiment never
    trains over an earlier one); ConfigError when out is itself a run or a capture."""
    if ckpt_lib.list_checkpoints(out / "checkpoints") or holds_capture(out):
        raise ConfigError(f"--out {out}: holds a run or a capture, whose files the experiment's would mix with; "
                          f"pick a new --out")
    taken = [r for r in run_dirs if ckpt_lib.list_checkpoints(out / r / "checkpoints")]
    if taken:
        raise NerfkitError(f"{out}: already holds model runs ({', '.join(taken)}); pick a new --out")


def budget_record(budget_minutes: float | None, max_steps: int | None) -> dict:
    """The budget as results.json keeps it: {"max_minutes", "max_steps", "text"}."""
    return {"max_minutes": budget_minutes, "max_steps": max_steps, "text": budget_text(budget_minutes, max_steps)}


def write_results(out: Path, results: dict, markdown: str) -> None:
    """OUT/results.json (the results dict) and OUT/results.md (its table)."""
    (out / "results.json").write_text(json.dumps(results, indent=2))
    (out / "results.md").write_text(markdown)


def apply_settings(cfg, budget_minutes: float | None, max_steps: int | None, seed: int | None,
                   val_every: int | None, train_split: str | None, val_split: str | None):
    """cfg with the experiment's shared settings: budget, seed, validation period and splits (None: keep)."""
    set_budget(cfg, budget_minutes, max_steps)
    if seed is not None:
        cfg.train.seed = int(seed)
    if val_every is not None:
        cfg.train.val_every = int(val_every)
    cfg.data.train_split, cfg.data.val_split = train_split, val_split
    return cfg


def _time_axis(runs: list[list[dict]]) -> tuple[str, float]:
    longest = max((r[-1].get("elapsed", 0) for r in runs if r), default=0)
    return ("time (min)", 60.0) if longest > 180 else ("time (s)", 1.0)


def overlay_plots(exp_dir: Path, labels: list[str], run_dirs: list[Path]) -> dict[str, str]:
    """Six overlaid plots (loss, train PSNR, val PSNR against step and against time) of
    several runs; returns {name: path relative to exp_dir}."""
    rows = [read_jsonl(r / "metrics.jsonl") for r in run_dirs]
    vrows = [read_jsonl(r / "val_metrics.jsonl") for r in run_dirs]
    tlabel, tscale = _time_axis(rows + vrows)
    specs = [
        ("loss", rows, "loss", "loss (MSE)", "Training loss", True),
        ("train_psnr", rows, "psnr", "PSNR (dB)", "Training PSNR (ray batch)", False),
        ("val_psnr", vrows, "psnr", "PSNR (dB)", "Validation PSNR", False),
    ]
    out = {}
    for name, table, key, ylabel, title, logy in specs:
        for axis in ("step", "time"):
            series = {}
            for label, rs in zip(labels, table):
                xs = [r["step"] if axis == "step" else r.get("elapsed", math.nan) / tscale for r in rs]
                series[label] = (xs, [r[key] for r in rs])
            rel = f"plots/{name}_vs_{axis}.png"
            plot_curves(series, exp_dir / rel, "step" if axis == "step" else tlabel, ylabel,
                        f"{title} against {axis}", logy=logy)
            out[f"{name}_vs_{axis}"] = rel
    return out


def gt_depth(data_dir: Path, name: str) -> np.ndarray | None:
    """Exact depth of a view where the data set has it (the procedural scene's r_K_depth.npy)."""
    p = data_dir / (str(Path(name).with_suffix("")) + "_depth.npy")
    if not p.is_file():
        return None
    try:
        d = np.load(p, allow_pickle=False)
    except (OSError, ValueError):
        return None
    return d if d.ndim == 2 else None


def image_grid(path: Path, gt: np.ndarray, renders: list[np.ndarray], depths: list[np.ndarray],
               titles: list[str], gt_depth: np.ndarray | None = None, background=(1.0, 1.0, 1.0)) -> None:
    """Labelled 2-row grid: top ground truth then each model's render, bottom each model's
    depth map (under the ground truth: the exact depth where known). Images [H, W, 3]."""
    import matplotlib.pyplot as plt

    h, w = gt.shape[:2]
    ncols = 1 + len(renders)
    scale = max(1.0, 160.0 / w)  # small images shown enlarged
    dpi = 100
    cw, ch = w * scale / dpi, h * scale / dpi
    lines = max(t.count("\n") + 1 for t in titles)
    fig, axes = plt.subplots(2, ncols, figsize=(ncols * (cw + 0.15) + 0.2, 2 * ch + 0.16 * lines + 0.6), dpi=dpi,
                             squeeze=False)
    cells = [(gt, "ground truth")] + list(zip(renders, titles))
    for ax, (img, title) in zip(axes[0], cells):
        ax.imshow(np.clip(img, 0, 1), interpolation="nearest")
        ax.set_title(title, fontsize=8)
    if gt_depth is not None:
        fg = np.isfinite(gt_depth)
        lo, hi = depth_range([np.where(fg, gt_depth, 0)], [fg.astype(np.float32)])
        axes[1][0].imshow(colorize_depth(np.where(fg, gt_depth, hi), fg.astype(np.float32), lo, hi, background),
                          interpolation="nearest")
        axes[1][0].set_title("exact depth", fontsize=8)
    else:
        axes[1][0].text(0.5, 0.5, "depth:\nsum_i w_i t_i\nnear = red\nfar = blue", ha="center", va="center",
                        fontsize=8, transform=axes[1][0].transAxes)
    for ax, img, title in zip(axes[1][1:], depths, titles):
        ax.imshow(np.clip(img, 0, 1), interpolation="nearest")
        ax.set_title(title.split("\n")[0] + ": depth", fontsize=8)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
        for s in ax.spines.values():
            s.set_visible(False)
    fig.tight_layout(pad=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def num_text(x, digits: int) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def labelled_grid(path: Path, cells: list[list[np.ndarray]], row_labels: list[str], col_titles: list[str],
                  notes: list[list[str]] | None = None, cell_px: int = 160) -> None:
    """A grid of images cells[r][c] ([h, w, 3] of any sizes), each enlarged (nearest neighbour: pixels stay
    visible) to cell_px on its long side; column titles on top, row labels on the left, an optional note
    under each cell."""
    import matplotlib.pyplot as plt

    nr, nc = len(cells), len(cells[0])
    dpi = 100
    side = cell_px / dpi
    fig, axes = plt.subplots(nr, nc, figsize=(nc * (side + 0.1) + 0.6, nr * (side + 0.35) + 0.3), dpi=dpi,
                             squeeze=False)
    for r in range(nr):
        for c in range(nc):
            ax = axes[r][c]
            ax.imshow(np.clip(cells[r][c], 0, 1), interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            for s in ax.spines.values():
                s.set_visible(False)
            if r == 0:
                ax.set_title(col_titles[c], fontsize=8)
            if c == 0:
                ax.set_ylabel(row_labels[r], fontsize=8)
            if notes and notes[r][c]:
                ax.set_xlabel(notes[r][c], fontsize=7)
    fig.tight_layout(pad=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
