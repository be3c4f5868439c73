"""Static HTML reports: one page per run (`write_report`) and one per experiment
(`write_experiment_report`).

A report is a single HTML file with inline CSS and no scripts, fonts or anything else
from the network. Every image, video and file it shows is linked by a path relative to
the report, so the folder can be opened straight from disk (file://), copied or zipped.
Videos are the H.264 MP4s that `nerfkit render` writes, embedded with <video>.
"""

from __future__ import annotations

import datetime as _dt
import html
import json
import os
from pathlib import Path
from urllib.parse import quote

from nerfkit.config import Config
from nerfkit.errors import NerfkitError
from nerfkit.flags import describe_model
from nerfkit.viz import read_jsonl

DEPTH_NOTE = (
    "Depth is the expected ray termination distance <code>D = &sum;<sub>i</sub> w<sub>i</sub> t<sub>i</sub></code>, "
    "with compositing weights <code>w<sub>i</sub> = T<sub>i</sub> (1 &minus; exp(&minus;&sigma;<sub>i</sub> "
    "&delta;<sub>i</sub>))</code> and sample positions <code>t<sub>i</sub></code> along the ray, in z-depth units "
    "(distance along the camera's viewing axis, the unit of near/far). The <code>.npy</code> files hold exactly "
    "that as float32 <code>[H, W]</code> arrays (<code>numpy.load</code>). The colour maps show "
    "<code>D / &sum;<sub>i</sub> w<sub>i</sub></code> (the depth given that the ray hit something), near = red, "
    "far = blue, each image set over its own robust (1st&ndash;99th percentile) range, faded to the background "
    "where the opacity <code>&sum;<sub>i</sub> w<sub>i</sub></code> is low."
)

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 0; color: #1d2330;
       background: #f4f5f7; line-height: 1.45; }
header { background: #1d2330; color: #fff; padding: 18px 28px; }
header h1 { margin: 0 0 4px 0; font-size: 1.5em; }
header p { margin: 0; color: #c7ccd6; }
header a { color: #9cc2ff; }
main { max-width: 1280px; margin: 0 auto; padding: 8px 28px 40px 28px; }
section { background: #fff; border: 1px solid #e0e3e8; border-radius: 8px; padding: 14px 20px; margin: 18px 0; }
h2 { font-size: 1.2em; margin: 0 0 10px 0; }
h3 { font-size: 1.0em; margin: 14px 0 6px 0; }
nav a { margin-right: 14px; }
table { border-collapse: collapse; margin: 6px 0 10px 0; font-size: 0.92em; }
th, td { border-bottom: 1px solid #e3e6ea; padding: 4px 10px; text-align: left; vertical-align: top; }
th { background: #f0f2f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.best td { font-weight: 600; }
.gallery { display: flex; flex-wrap: wrap; gap: 14px; align-items: flex-start; }
.plots { display: grid; grid-template-columns: repeat(auto-fill, minmax(360px, 1fr)); gap: 14px; }
.plots.two { grid-template-columns: repeat(2, minmax(0, 1fr)); }
.plots img { width: 100%; height: auto; image-rendering: auto; }
figure { margin: 0; }
figure img, figure video { display: block; max-width: 100%; height: auto; border: 1px solid #d5d9df;
                           background: #fff; image-rendering: pixelated; }
figcaption { font-size: 0.85em; color: #555d6b; margin-top: 3px; max-width: 640px; }
.cfg { display: flex; flex-wrap: wrap; gap: 18px; }
.cfg table { min-width: 220px; }
.note { font-size: 0.9em; color: #444b57; }
code { background: #f0f2f5; padding: 0 3px; border-radius: 3px; }
.muted { color: #7a8190; }
"""

# Small images (tests, thumbnails) are shown enlarged to at least this width, pixelated.
MIN_DISPLAY_WIDTH = 192


# -- small HTML helpers ---------------------------------------------------------------------------

def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _url(path: Path, base: Path) -> str:
    """A relative, percent-encoded URL from the folder `base` to `path`."""
    rel = os.path.relpath(Path(path).resolve(), Path(base).resolve())
    return quote(Path(rel).as_posix())


def _image_size(path: Path) -> tuple[int, int] | None:
    try:
        from PIL import Image

        with Image.open(path) as im:
            return im.size
    except Exception:  # unreadable or not an image: no size hint
        return None


def _display_width(natural: int) -> int:
    if natural >= MIN_DISPLAY_WIDTH:
        return natural
    return natural * -(-MIN_DISPLAY_WIDTH // natural)  # integer upscale, crisp pixels


def _img(path: Path, base: Path, alt: str, caption: str = "", max_width: int | None = None) -> str:
    url = _url(path, base)
    size = _image_size(path)
    attrs = ""
    if size:
        w = _display_width(size[0])
        if max_width:
            w = min(w, max_width)
        attrs = f' width="{w}"'
    cap = f"<figcaption>{caption}</figcaption>" if caption else ""
    return f'<figure><a href="{_e(url)}"><img src="{_e(url)}" alt="{_e(alt)}"{attrs}></a>{cap}</figure>'


def _video(path: Path, base: Path, caption: str = "", width: int | None = None) -> str:
    url = _url(path, base)
    w = f' width="{_display_width(width)}"' if width else ""
    cap = f'<figcaption>{caption} (<a href="{_e(url)}">{_e(Path(path).name)}</a>)</figcaption>'
    return (f'<figure><video controls muted loop autoplay playsinline preload="auto"{w} src="{_e(url)}">'
            f'</video>{cap}</figure>')


def _link(path: Path, base: Path, text: str | None = None) -> str:
    return f'<a href="{_e(_url(path, base))}">{_e(text if text is not None else Path(path).name)}</a>'


def _table(header: list[str], rows: list[list[str]], numeric: set[int] = frozenset(),
           row_classes: list[str] | None = None) -> str:
    """rows hold ready-made HTML cells (escape text before passing it)."""
    head = "<thead><tr>" + "".join(f"<th>{h}</th>" for h in header) + "</tr></thead>" if any(header) else ""
    out = [f"<table>{head}<tbody>"]
    for k, row in enumerate(rows):
        cls = f' class="{row_classes[k]}"' if row_classes and row_classes[k] else ""
        cells = "".join(f'<td class="num">{c}</td>' if j in numeric else f"<td>{c}</td>" for j, c in enumerate(row))
        out.append(f"<tr{cls}>{cells}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _page(title: str, subtitle: str, sections: list[tuple[str, str, str]]) -> str:
    """sections: (anchor id, heading, body html)."""
    nav = " ".join(f'<a href="#{_e(a)}">{_e(h)}</a>' for a, h, body in sections if body)
    body = "".join(f'<section id="{_e(a)}"><h2>{_e(h)}</h2>{b}</section>' for a, h, b in sections if b)
    stamp = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
        f"<title>{_e(title)}</title><style>{CSS}</style></head><body>"
        f"<header><h1>{_e(title)}</h1><p>{subtitle}</p></header>"
        f"<main><nav>{nav}</nav>{body}"
        f'<p class="muted">written by nerfkit on {_e(stamp)}; a static page: all links are relative, '
        "nothing is loaded from the network.</p></main></body></html>\n"
    )


def _write(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def _minutes(seconds: float | None) -> str:
    if seconds is None:
        return "n/a"
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _fmt(x, digits: int = 2) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return None


# -- one run --------------------------------------------------------------------------------------

def _config_html(cfg: dict | None, base: Path, config_path: Path) -> str:
    if not cfg:
        return ""
    parts = ['<div class="cfg">']
    for section, values in cfg.items():
        if not isinstance(values, dict):
            continue
        rows = [[f"<code>{_e(k)}</code>", _e(json.dumps(v))] for k, v in values.items()]
        parts.append(f"<div><h3>{_e(section)}</h3>{_table(['key', 'value'], rows)}</div>")
    parts.append("</div>")
    if config_path.is_file():
        parts.append(f'<p class="note">The resolved config: {_link(config_path, base)} '
                     "(what <code>--resume</code>, <code>eval</code> and <code>render</code> rebuild the model from).</p>")
    return "".join(parts)


def _summary_html(run: Path, cfg: dict | None, scene: dict | None, rows: list[dict], vrows: list[dict]) -> str:
    items = []
    if scene:
        items.append(["data", _e(scene.get("data_dir", "?"))])
        items.append(["images", _e(f"{scene.get('width')}x{scene.get('height')}, {scene.get('n_train')} train / "
                                   f"{scene.get('n_val')} val views")])
    if cfg:
        try:
            items.append(["model", _e(describe_model(Config.from_dict(cfg)))])
        except NerfkitError as e:
            items.append(["model", _e(f"config.json not readable: {e}")])
        d = cfg.get("data", {})
        items.append(["splits", _e(f"train {d.get('train_split')}; val {d.get('val_split')}")])
    if vrows and scene:
        views = vrows[-1].get("views", [])
        items.append(["validation views", _e(f"{len(views)} of {scene.get('n_val')} (views {', '.join(map(str, views))}"
                                             f", evenly spaced); nerfkit eval scores them all")])
    if rows:
        last = rows[-1]
        items.append(["steps", _e(f"{last['step']} in {_minutes(last.get('elapsed'))} (the last step taken)")])
        items.append(["last train batch", _e(f"loss {last['loss']:.5f}, PSNR {last['psnr']:.2f} dB")])
    if vrows:
        best = max(vrows, key=lambda r: r["psnr"])
        items.append(["validation PSNR", _e(f"{vrows[-1]['psnr']:.2f} dB at step {vrows[-1]['step']} "
                                            f"(best {best['psnr']:.2f} dB at step {best['step']})")])
    files = [p for p in (run / "config.json", run / "scene.json", run / "metrics.jsonl", run / "val_metrics.jsonl")
             if p.is_file()]
    if files:
        items.append(["files", " ".join(_link(p, run) for p in files)])
    return _table(["", ""], [[_e(k), v] for k, v in items]) if items else ""


def _curves_html(run: Path) -> str:
    names = [("train_loss.png", "training loss (MSE of the step's ray batch)"),
             ("train_psnr.png", "training PSNR (of the step's ray batch)"),
             ("val_psnr.png", "validation PSNR (mean over the validation views)")]
    figs = [_img(run / "plots" / n, run, n, _e(c)) for n, c in names if (run / "plots" / n).is_file()]
    return f'<div class="plots">{"".join(figs)}</div>' if figs else ""


def _latest_val_dir(run: Path) -> Path | None:
    dirs = sorted(p for p in (run / "val").glob("step_*") if p.is_dir() and any(p.glob("view_*.png")))
    return dirs[-1] if dirs else None


def _validation_html(run: Path, vrows: list[dict]) -> str:
    vdir = _latest_val_dir(run)
    if vdir is None:
        return ""
    step = int(vdir.name.split("_")[1])
    row = next((r for r in reversed(vrows) if r.get("step") == step), None)
    scores = dict(zip(row.get("views", []), row.get("per_view", []))) if row else {}
    figs = []
    for png in sorted(vdir.glob("view_*.png")):
        if png.stem.endswith("_depth"):
            continue
        k = int(png.stem.split("_")[1])
        npy = vdir / f"{png.stem}_depth.npy"
        cap = f"val view {k}"
        if k in scores:
            cap += f": PSNR {scores[k]:.2f} dB"
        cap = _e(cap) + " &middot; ground truth | render | depth"
        if npy.is_file():
            cap += f" &middot; depth array {_link(npy, run)}"
        figs.append(_img(png, run, f"validation view {k} at step {step}", cap))
    older = sorted(p for p in (run / "val").glob("step_*") if p.is_dir() and p != vdir)
    more = ""
    if older:
        more = ('<p class="note">Earlier validations: '
                + ", ".join(_link(p, run, f"step {int(p.name.split('_')[1])}") for p in older) + "</p>")
    return (f"<p>Latest validation, step {step}. Each image: ground truth, the model's render, its depth map.</p>"
            f'<div class="gallery">{"".join(figs)}</div>{more}')


def _eval_html(run: Path, max_gallery: int = 6) -> str:
    evals = []
    for path in sorted(run.glob("eval_*.json")):
        res = _read_json(path)
        if res and "psnr" in res:
            evals.append((path, res))
    if not evals:
        return ""
    def title_of(r):  # the field, or the baked scene (nerfkit eval --baked): two results of one split
        return f"{r.get('split')} ({'baked scene' if r.get('baked') else 'field'})"

    rows = [[_e(title_of(r)), _e(r.get("step")), _e(f"{r.get('width')}x{r.get('height')}"), _e(r.get("n_views")),
             _fmt(r.get("psnr")), _fmt(r.get("ssim"), 4), _fmt(r.get("seconds_per_view")), _link(p, run)]
            for p, r in evals]
    parts = [_table(["split", "step", "size", "views", "PSNR (dB)", "SSIM", "s / view", "file"], rows,
                    numeric={1, 3, 4, 5, 6})]
    for path, res in evals:
        rdir = run / path.stem
        views = res.get("per_view", [])
        worst = res.get("worst") or []
        if len(views) > 1 and worst:
            parts.append(f"<p>{_e(title_of(res))}, worst views: " + ", ".join(
                _e(f"{w['view']} ({Path(w['name']).name}) {w['psnr']:.2f} dB") + (" <b>outlier</b>" if w["outlier"]
                                                                                  else "") for w in worst)
                + (f" (an outlier is more than {res.get('outlier_db', 3):g} dB below the median view: look at that "
                   f"photo)"
                   if any(w["outlier"] for w in worst) else "") + "</p>")
        prow = []
        for v in views:
            k = v["view"]
            links = [_link(rdir / f"view_{k:03d}_{s}", run, s) for s in ("rgb.png", "depth.png", "depth.npy")
                     if (rdir / f"view_{k:03d}_{s}").is_file()]
            prow.append([_e(k), _e(v.get("name", "")), _fmt(v.get("psnr")), _fmt(v.get("ssim"), 4), " ".join(links)])
        parts.append(f"<details><summary>{_e(title_of(res))}: per-view scores ({len(views)} views)</summary>"
                     + _table(["view", "name", "PSNR (dB)", "SSIM", "files"], prow, numeric={0, 2, 3}) + "</details>")
        figs = []
        for v in views[:max_gallery]:
            k = v["view"]
            for s, what in (("rgb", "render"), ("depth", "depth")):
                p = rdir / f"view_{k:03d}_{s}.png"
                if p.is_file():
                    figs.append(_img(p, run, f"{res.get('split')} view {k} {what}",
                                     _e(f"view {k} {what}" + (f", PSNR {v['psnr']:.2f} dB" if s == "rgb" else ""))))
        if figs:
            shown = f"the first {min(len(views), max_gallery)} views" if len(views) > max_gallery else "all views"
            parts.append(f"<h3>{_e(title_of(res))}: renders and depth ({shown})</h3>"
                         f'<div class="gallery">{"".join(figs)}</div>')
    return "".join(parts)


def _videos_html(run: Path, base: Path | None = None, label: str = "") -> str:
    base = base or run
    parts = []
    for rdir in sorted(p for p in (run / "renders").glob("*") if p.is_dir()):
        info = _read_json(rdir / "render.json") or {}
        vids = [(rdir / n, what) for n, what in (("rgb.mp4", "RGB"), ("depth.mp4", "depth")) if (rdir / n).is_file()]
        if not vids:
            continue
        desc = rdir.name
        if info:
            desc += f": {info.get('frames')} frames at {info.get('width')}x{info.get('height')}"
            if info.get("seconds_per_frame") is not None:
                desc += f", {info['seconds_per_frame']:.2f} s/frame"
        figs = [_video(p, base, _e(f"{label}{what}"), info.get("width")) for p, what in vids]
        npys = sorted(rdir.glob("depth_*.npy"))
        extra = (f'<p class="note">Per-frame PNGs and depth arrays in {_link(rdir, base, rdir.name + "/")} '
                 f"({len(npys)} <code>depth_K.npy</code>).</p>") if npys else ""
        parts.append(f"<h3>{_e(desc)}</h3><div class=\"gallery\">{''.join(figs)}</div>{extra}")
    return "".join(parts)


def _exports_html(run: Path) -> str:
    """The latest export of each kind (nerfkit export): its picture, file and figures."""
    from nerfkit.export.run import read_records

    figs = []
    for kind, rec in read_records(run).items():
        pic = run / "exports" / str(rec.get("picture", ""))
        facts = {"mesh": "{vertices} vertices, {faces} faces, " + (
                     "threshold {threshold:.4g}" if rec.get("method", "levelset") == "levelset" else
                     "{method} of {views} views" + (", closed" if rec.get("closed_manifold") else "")),
                 "pointcloud": "{points} points from {views} views",
                 "cameras": "{frames} cameras",
                 "splat": "{gaussians} Gaussians, SH degree {sh_degree}, read back and rendered"}[kind]
        if kind == "pointcloud" and "source" in rec:  # a splat run's centres
            facts = "{points} points ({source})"
        try:
            facts = facts.format(**rec)
        except (KeyError, ValueError, TypeError):
            facts = ""
        caption = _e(f"{kind}: {Path(str(rec.get('file', ''))).name} ({facts}, step {rec.get('step', '-')})")
        if pic.is_file():
            figs.append(_img(pic, run, kind, caption))
    return f'<div class="gallery">{"".join(figs)}</div>' if figs else ""


def write_report(run_dir: str | Path) -> Path:
    """Write RUN_DIR/report.html: config, curves, latest validation images beside ground
    truth, depth maps, the eval tables if present and the rendered videos. Safe to call on a
    run in progress or a partial run folder (missing parts are left out). Returns the path."""
    run = Path(run_dir)
    if not (run / "config.json").is_file():
        from nerfkit.errors import NerfkitError

        raise NerfkitError(f"{run}: not a nerfkit run folder (no config.json)")
    cfg = _read_json(run / "config.json")
    scene = _read_json(run / "scene.json")
    rows = read_jsonl(run / "metrics.jsonl")
    vrows = read_jsonl(run / "val_metrics.jsonl")
    subtitle = _e(f"run folder {run.resolve().name}")
    if scene:
        subtitle += " &middot; data " + _e(Path(scene.get("data_dir", "")).name or scene.get("data_dir", ""))
    videos = _videos_html(run)
    depth = DEPTH_NOTE if (_latest_val_dir(run) or any(run.glob("eval_*.json")) or videos) else ""
    sections = [
        ("summary", "Summary", _summary_html(run, cfg, scene, rows, vrows)),
        ("curves", "Curves", _curves_html(run)),
        ("validation", "Validation images", _validation_html(run, vrows)),
        ("eval", "Evaluation", _eval_html(run)),
        ("videos", "Videos", videos),
        ("exports", "Exports", _exports_html(run)),
        ("depth", "Depth", f'<p class="note">{depth}</p>' if depth else ""),
        ("config", "Config", _config_html(cfg, run, run / "config.json")),
    ]
    return _write(run / "report.html", _page(f"nerfkit run: {run.resolve().name}", subtitle, sections))


# -- an experiment --------------------------------------------------------------------------------

def write_experiment_report(exp_dir: str | Path, results: dict | None = None) -> Path:
    """Write EXP_DIR/report.html tying the models of an experiment together, from
    `results` (or EXP_DIR/results.json) as written by nerfkit.experiments: the results
    table, the overlaid curves, the validation image grids, each model's videos and links
    to each model's own run report."""
    exp = Path(exp_dir)
    if results is None:
        results = _read_json(exp / "results.json")
        if results is None:
            from nerfkit.errors import NerfkitError

            raise NerfkitError(f"{exp / 'results.json'}: missing or unreadable; is {exp} an experiment folder?")
    if results.get("experiment") == "antialias":
        from nerfkit.experiments.antialias import write_antialias_report

        return write_antialias_report(exp, results)
    models = results.get("models", [])
    title = results.get("title", "nerfkit experiment")

    # Setup and results table.
    best = max((m.get("psnr") for m in models if m.get("psnr") is not None), default=None)
    rows, classes = [], []
    for m in models:
        run = exp / m["run_dir"]
        rep = run / "report.html"
        name = _e(m["label"]) + (f" ({_link(rep, exp, 'run report')})" if rep.is_file() else "")
        rows.append([name, _e(m.get("description", "")), _e(m.get("steps")), _e(_minutes(m.get("train_seconds"))),
                     _fmt(m.get("final_train_psnr")), _fmt(m.get("val_psnr_training")), _fmt(m.get("psnr")),
                     _fmt(m.get("ssim"), 4)])
        classes.append("best" if best is not None and m.get("psnr") == best else "")
    ev = results.get("eval", {})
    budget = results.get("budget", {})
    intro = f"<p>{_e(results['question'])}</p>" if results.get("question") else ""
    setup = _table(["", ""], [
        ["data", _e(results.get("data_dir", ""))],
        ["preset", f"<code>{_e(results.get('preset'))}</code> (only the positional-encoding settings differ)"],
        ["budget per model", _e(budget.get("text", ""))],
        ["seed", _e(results.get("seed"))],
        ["validation metrics", _e(f"{ev.get('split')}, every {ev.get('every')} view(s): {ev.get('n_views')} views")],
        ["files", " ".join(_link(exp / n, exp) for n in ("results.md", "results.json") if (exp / n).is_file())],
    ])
    table = _table(["model", "encoding", "steps", "train time", "train PSNR (dB)", "val PSNR, training (dB)",
                    "val PSNR (dB)", "val SSIM"], rows, numeric={2, 4, 5, 6, 7}, row_classes=classes)
    results_html = (intro + setup + table +
                    '<p class="note">val PSNR / SSIM: every view of the evaluation set above, after training. '
                    "val PSNR, training: the last in-training validation (the run's <code>--val-views</code>). "
                    "train PSNR: the last logged training batch. Bold: the best val PSNR.</p>")

    # Curves: one row per metric, step and time side by side.
    plots = results.get("plots", {})
    figs = []
    for key in ("loss", "train_psnr", "val_psnr"):
        for axis in ("step", "time"):
            p = plots.get(f"{key}_vs_{axis}")
            if p and (exp / p).is_file():
                figs.append(_img(exp / p, exp, f"{key} vs {axis}", _e(f"{key.replace('_', ' ')} against {axis}")))
    curves = (f'<p class="note">Left: against training step; right: against wall time (compile and validation '
              f'included).</p><div class="plots two">{"".join(figs)}</div>') if figs else ""

    # Validation grids.
    gfigs = []
    for g in results.get("grids", []):
        p = exp / g["path"]
        if p.is_file():
            cap = _e(f"val view {g['view']} ({g.get('name', '')}): ground truth, then each model's render (top) "
                     "and depth map (bottom)")
            gfigs.append(_img(p, exp, f"grid of val view {g['view']}", cap))
    grids = f'<div class="gallery">{"".join(gfigs)}</div>' if gfigs else ""

    # Videos: each model's orbit, RGB and depth.
    vids = []
    for m in models:
        figs = []
        for key, what in (("orbit_video", "RGB"), ("depth_video", "depth")):
            if m.get(key) and (exp / m[key]).is_file():
                figs.append(_video(exp / m[key], exp, _e(f"{m['label']} {what}"), m.get("video_width")))
        if figs:
            vids.append(f"<h3>{_e(m['label'])}: {_e(m.get('description', ''))}</h3>"
                        f'<div class="gallery">{"".join(figs)}</div>')
    videos = "".join(vids)

    # Per-model configs (links) and the run folders.
    links = []
    for m in models:
        run = exp / m["run_dir"]
        items = [_link(run, exp, m["run_dir"] + "/")]
        for n in ("report.html", "config.json", "metrics.jsonl", "val_metrics.jsonl"):
            if (run / n).is_file():
                items.append(_link(run / n, exp, n))
        links.append([_e(m["label"]), " ".join(items)])
    runs = _table(["model", "files"], links) if links else ""

    subtitle = _e(results.get("subtitle", ""))
    sections = [
        ("results", "Results", results_html),
        ("curves", "Curves", curves),
        ("views", "Validation views", grids),
        ("videos", "Orbit videos", videos),
        ("depth", "Depth", f'<p class="note">{DEPTH_NOTE}</p>'),
        ("runs", "Run folders", runs),
    ]
    return _write(exp / "report.html", _page(title, subtitle, sections))
