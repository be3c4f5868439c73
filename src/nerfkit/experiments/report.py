"""The static HTML report of an experiment (`write_experiment_report`): the models of one comparison
side by side, from the results.json that nerfkit.experiments writes."""

from __future__ import annotations

from pathlib import Path

from nerfkit.core.errors import NerfkitError
from nerfkit.experiments.antialias import write_antialias_report
from nerfkit.report import html as h
from nerfkit.report.run import DEPTH_NOTE


def write_experiment_report(exp_dir: str | Path, results: dict | None = None) -> Path:
    """Write EXP_DIR/report.html tying the models of an experiment together, from
    `results` (or EXP_DIR/results.json) as written by nerfkit.experiments: the results
    table, the overlaid curves, the validation image grids, each model's videos and links
    to each model's own run report."""
    exp = Path(exp_dir)
    if results is None:
        results = h.read_json(exp / "results.json")
        if results is None:
            raise NerfkitError(f"{exp / 'results.json'}: missing or unreadable; is {exp} an experiment folder?")
    if results.get("experiment") == "antialias":
        return write_antialias_report(exp, results)
    models = results.get("models", [])
    title = results.get("title", "nerfkit experiment")
    subtitle = h.e(results.get("subtitle", ""))
    sections = [
        ("results", "Results", results_section(exp, results)),
        ("curves", "Curves", curves_section(exp, results.get("plots", {}))),
        ("views", "Validation views", grids_section(exp, results.get("grids", []))),
        ("videos", "Orbit videos", videos_section(exp, models)),
        ("depth", "Depth", f'<p class="note">{DEPTH_NOTE}</p>'),
        ("runs", "Run folders", runs_section(exp, models)),
    ]
    return h.write(exp / "report.html", h.page(title, subtitle, sections))


def results_section(exp: Path, results: dict) -> str:
    """The question, the setup table and the results table (one row per model, the best val PSNR in bold)."""
    models = results.get("models", [])
    best = max((m.get("psnr") for m in models if m.get("psnr") is not None), default=None)
    rows, classes = [], []
    for m in models:
        run = exp / m["run_dir"]
        rep = run / "report.html"
        name = h.e(m["label"]) + (f" ({h.link(rep, exp, 'run report')})" if rep.is_file() else "")
        rows.append([name, h.e(m.get("description", "")), h.e(m.get("steps")), h.e(h.minutes(m.get("train_seconds"))),
                     h.fmt(m.get("final_train_psnr")), h.fmt(m.get("val_psnr_training")), h.fmt(m.get("psnr")),
                     h.fmt(m.get("ssim"), 4)])
        classes.append("best" if best is not None and m.get("psnr") == best else "")
    ev = results.get("eval", {})
    budget = results.get("budget", {})
    intro = f"<p>{h.e(results['question'])}</p>" if results.get("question") else ""
    setup = h.table(["", ""], [
        ["data", h.e(results.get("data_dir", ""))],
        ["preset", f"<code>{h.e(results.get('preset'))}</code> (only the positional-encoding settings differ)"],
        ["budget per model", h.e(budget.get("text", ""))],
        ["seed", h.e(results.get("seed"))],
        ["validation metrics", h.e(f"{ev.get('split')}, every {ev.get('every')} view(s): {ev.get('n_views')} views")],
        ["files", " ".join(h.link(exp / n, exp) for n in ("results.md", "results.json") if (exp / n).is_file())],
    ])
    table = h.table(["model", "encoding", "steps", "train time", "train PSNR (dB)", "val PSNR, training (dB)",
                    "val PSNR (dB)", "val SSIM"], rows, numeric={2, 4, 5, 6, 7}, row_classes=classes)
    return (intro + setup + table +
            '<p class="note">val PSNR / SSIM: every view of the evaluation set above, after training. '
            "val PSNR, training: the last in-training validation (the run's <code>--val-views</code>). "
            "train PSNR: the last logged training batch. Bold: the best val PSNR.</p>")


def curves_section(exp: Path, plots: dict) -> str:
    """The overlaid curves: one row per metric, against step and against time side by side ("" without any)."""
    figs = []
    for key in ("loss", "train_psnr", "val_psnr"):
        for axis in ("step", "time"):
            p = plots.get(f"{key}_vs_{axis}")
            if p and (exp / p).is_file():
                figs.append(h.img(exp / p, exp, f"{key} vs {axis}", h.e(f"{key.replace('_', ' ')} against {axis}")))
    return (f'<p class="note">Left: against training step; right: against wall time (compile and validation '
            f'included).</p><div class="plots two">{"".join(figs)}</div>') if figs else ""


def grids_section(exp: Path, grids: list[dict]) -> str:
    """The validation image grids that exist, as a gallery ("" without any)."""
    gfigs = []
    for g in grids:
        p = exp / g["path"]
        if p.is_file():
            cap = h.e(f"val view {g['view']} ({g.get('name', '')}): ground truth, then each model's render (top) "
                     "and depth map (bottom)")
            gfigs.append(h.img(p, exp, f"grid of val view {g['view']}", cap))
    return f'<div class="gallery">{"".join(gfigs)}</div>' if gfigs else ""


def videos_section(exp: Path, models: list[dict]) -> str:
    """Each model's orbit videos (RGB and depth) under its name."""
    vids = []
    for m in models:
        figs = []
        for key, what in (("orbit_video", "RGB"), ("depth_video", "depth")):
            if m.get(key) and (exp / m[key]).is_file():
                figs.append(h.video(exp / m[key], exp, h.e(f"{m['label']} {what}"), m.get("video_width")))
        if figs:
            vids.append(f"<h3>{h.e(m['label'])}: {h.e(m.get('description', ''))}</h3>"
                        f'<div class="gallery">{"".join(figs)}</div>')
    return "".join(vids)


def runs_section(exp: Path, models: list[dict]) -> str:
    """A table of each model's run folder and the files in it (report, config, logs)."""
    links = []
    for m in models:
        run = exp / m["run_dir"]
        items = [h.link(run, exp, m["run_dir"] + "/")]
        for n in ("report.html", "config.json", "metrics.jsonl", "val_metrics.jsonl"):
            if (run / n).is_file():
                items.append(h.link(run / n, exp, n))
        links.append([h.e(m["label"]), " ".join(items)])
    return h.table(["model", "files"], links) if links else ""
