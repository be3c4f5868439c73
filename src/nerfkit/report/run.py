"""The static HTML report of one run (`write_report`): summary, curves, validation views, evaluation,
videos, exports. Videos are the H.264 MP4s that `nerfkit render` writes, embedded with <video>.
"""

from __future__ import annotations

import json
from pathlib import Path

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.viz import read_jsonl
from nerfkit.export.registry import EXPORTERS, exporter
from nerfkit.report import html as h
from nerfkit.run.folder import RunFolder
from nerfkit.training.flags import describe_model

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

def _config_html(cfg: dict | None, base: Path, config_path: Path) -> str:
    if not cfg:
        return ""
    parts = ['<div class="cfg">']
    for section, values in cfg.items():
        if not isinstance(values, dict):
            continue
        rows = [[f"<code>{h.e(k)}</code>", h.e(json.dumps(v))] for k, v in values.items()]
        parts.append(f"<div><h3>{h.e(section)}</h3>{h.table(['key', 'value'], rows)}</div>")
    parts.append("</div>")
    if config_path.is_file():
        parts.append(f'<p class="note">The resolved config: {h.link(config_path, base)} '
                     "(what <code>--resume</code>, <code>eval</code> and <code>render</code> rebuild the model from).</p>")
    return "".join(parts)


def _summary_html(run: Path, cfg: dict | None, scene: dict | None, rows: list[dict], vrows: list[dict]) -> str:
    items = []
    if scene:
        items.append(["data", h.e(scene.get("data_dir", "?"))])
        items.append(["images", h.e(f"{scene.get('width')}x{scene.get('height')}, {scene.get('n_train')} train / "
                                   f"{scene.get('n_val')} val views")])
    if cfg:
        try:
            items.append(["model", h.e(describe_model(Config.from_dict(cfg)))])
        except NerfkitError as e:
            items.append(["model", h.e(f"config.json not readable: {e}")])
        d = cfg.get("data", {})
        items.append(["splits", h.e(f"train {d.get('train_split')}; val {d.get('val_split')}")])
    if vrows and scene:
        views = vrows[-1].get("views", [])
        items.append(["validation views", h.e(f"{len(views)} of {scene.get('n_val')} (views {', '.join(map(str, views))}"
                                             f", evenly spaced); nerfkit eval scores them all")])
    if rows:
        last = rows[-1]
        items.append(["steps", h.e(f"{last['step']} in {h.minutes(last.get('elapsed'))} (the last step taken)")])
        items.append(["last train batch", h.e(f"loss {last['loss']:.5f}, PSNR {last['psnr']:.2f} dB")])
    if vrows:
        best = max(vrows, key=lambda r: r["psnr"])
        items.append(["validation PSNR", h.e(f"{vrows[-1]['psnr']:.2f} dB at step {vrows[-1]['step']} "
                                            f"(best {best['psnr']:.2f} dB at step {best['step']})")])
    files = [p for p in (run / "config.json", run / "scene.json", run / "metrics.jsonl", run / "val_metrics.jsonl")
             if p.is_file()]
    if files:
        items.append(["files", " ".join(h.link(p, run) for p in files)])
    return h.table(["", ""], [[h.e(k), v] for k, v in items]) if items else ""


def _curves_html(run: Path) -> str:
    names = [("train_loss.png", "training loss (MSE of the step's ray batch)"),
             ("train_psnr.png", "training PSNR (of the step's ray batch)"),
             ("val_psnr.png", "validation PSNR (mean over the validation views)")]
    figs = [h.img(run / "plots" / n, run, n, h.e(c)) for n, c in names if (run / "plots" / n).is_file()]
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
        cap = h.e(cap) + " &middot; ground truth | render | depth"
        if npy.is_file():
            cap += f" &middot; depth array {h.link(npy, run)}"
        figs.append(h.img(png, run, f"validation view {k} at step {step}", cap))
    older = sorted(p for p in (run / "val").glob("step_*") if p.is_dir() and p != vdir)
    more = ""
    if older:
        more = ('<p class="note">Earlier validations: '
                + ", ".join(h.link(p, run, f"step {int(p.name.split('_')[1])}") for p in older) + "</p>")
    return (f"<p>Latest validation, step {step}. Each image: ground truth, the model's render, its depth map.</p>"
            f'<div class="gallery">{"".join(figs)}</div>{more}')


def _eval_html(run: Path, max_gallery: int = 6) -> str:
    evals = []
    for path in sorted(run.glob("eval_*.json")):
        res = h.read_json(path)
        if res and "psnr" in res:
            evals.append((path, res))
    if not evals:
        return ""
    def title_of(r):  # the field, or the baked scene (nerfkit eval --baked): two results of one split
        return f"{r.get('split')} ({'baked scene' if r.get('baked') else 'field'})"

    rows = [[h.e(title_of(r)), h.e(r.get("step")), h.e(f"{r.get('width')}x{r.get('height')}"), h.e(r.get("n_views")),
             h.fmt(r.get("psnr")), h.fmt(r.get("ssim"), 4), h.fmt(r.get("seconds_per_view")), h.link(p, run)]
            for p, r in evals]
    parts = [h.table(["split", "step", "size", "views", "PSNR (dB)", "SSIM", "s / view", "file"], rows,
                    numeric={1, 3, 4, 5, 6})]
    for path, res in evals:
        rdir = run / path.stem
        views = res.get("per_view", [])
        worst = res.get("worst") or []
        if len(views) > 1 and worst:
            parts.append(f"<p>{h.e(title_of(res))}, worst views: " + ", ".join(
                h.e(f"{w['view']} ({Path(w['name']).name}) {w['psnr']:.2f} dB") + (" <b>outlier</b>" if w["outlier"]
                                                                                  else "") for w in worst)
                + (f" (an outlier is more than {res.get('outlier_db', 3):g} dB below the median view: look at that "
                   f"photo)"
                   if any(w["outlier"] for w in worst) else "") + "</p>")
        prow = []
        for v in views:
            k = v["view"]
            links = [h.link(rdir / f"view_{k:03d}_{s}", run, s) for s in ("rgb.png", "depth.png", "depth.npy")
                     if (rdir / f"view_{k:03d}_{s}").is_file()]
            prow.append([h.e(k), h.e(v.get("name", "")), h.fmt(v.get("psnr")), h.fmt(v.get("ssim"), 4), " ".join(links)])
        parts.append(f"<details><summary>{h.e(title_of(res))}: per-view scores ({len(views)} views)</summary>"
                     + h.table(["view", "name", "PSNR (dB)", "SSIM", "files"], prow, numeric={0, 2, 3}) + "</details>")
        figs = []
        for v in views[:max_gallery]:
            k = v["view"]
            for s, what in (("rgb", "render"), ("depth", "depth")):
                p = rdir / f"view_{k:03d}_{s}.png"
                if p.is_file():
                    figs.append(h.img(p, run, f"{res.get('split')} view {k} {what}",
                                     h.e(f"view {k} {what}" + (f", PSNR {v['psnr']:.2f} dB" if s == "rgb" else ""))))
        if figs:
            shown = f"the first {min(len(views), max_gallery)} views" if len(views) > max_gallery else "all views"
            parts.append(f"<h3>{h.e(title_of(res))}: renders and depth ({shown})</h3>"
                         f'<div class="gallery">{"".join(figs)}</div>')
    return "".join(parts)


def _videos_html(run: Path, base: Path | None = None, label: str = "") -> str:
    base = base or run
    parts = []
    for rdir in sorted(p for p in (run / "renders").glob("*") if p.is_dir()):
        info = h.read_json(rdir / "render.json") or {}
        vids = [(rdir / n, what) for n, what in (("rgb.mp4", "RGB"), ("depth.mp4", "depth")) if (rdir / n).is_file()]
        if not vids:
            continue
        desc = rdir.name
        if info:
            desc += f": {info.get('frames')} frames at {info.get('width')}x{info.get('height')}"
            if info.get("seconds_per_frame") is not None:
                desc += f", {info['seconds_per_frame']:.2f} s/frame"
        figs = [h.video(p, base, h.e(f"{label}{what}"), info.get("width")) for p, what in vids]
        npys = sorted(rdir.glob("depth_*.npy"))
        extra = (f'<p class="note">Per-frame PNGs and depth arrays in {h.link(rdir, base, rdir.name + "/")} '
                 f"({len(npys)} <code>depth_K.npy</code>).</p>") if npys else ""
        parts.append(f"<h3>{h.e(desc)}</h3><div class=\"gallery\">{''.join(figs)}</div>{extra}")
    return "".join(parts)


def _exports_html(run: Path) -> str:
    """The latest export of each kind (nerfkit export): its picture, file and figures."""

    figs = []
    order = list(EXPORTERS)
    records = RunFolder(run).records()
    for kind in sorted(records, key=lambda k: order.index(k) if k in order else len(order)):
        rec = records[kind]
        pic = run / "exports" / str(rec.get("picture", ""))
        try:
            facts = exporter(kind).facts(rec)
        except (ConfigError, KeyError, ValueError, TypeError):  # an exporter no longer listed, an older record
            facts = ""
        caption = h.e(f"{kind}: {Path(str(rec.get('file', ''))).name} ({facts}, step {rec.get('step', '-')})")
        if pic.is_file():
            figs.append(h.img(pic, run, kind, caption))
    return f'<div class="gallery">{"".join(figs)}</div>' if figs else ""


def write_report(run_dir: str | Path) -> Path:
    """Write RUN_DIR/report.html: config, curves, latest validation images beside ground
    truth, depth maps, the eval tables if present and the rendered videos. Safe to call on a
    run in progress or a partial run folder (missing parts are left out); a config.json that is
    not JSON is refused (RunFolder.config_json). Returns the path."""
    run = Path(run_dir)
    if not (run / "config.json").is_file():
        raise NerfkitError(f"{run}: not a nerfkit run folder (no config.json)")
    cfg = RunFolder(run).config_json()  # refused when cut short: a page without the model would look like none
    scene = h.read_json(run / "scene.json")
    rows = read_jsonl(run / "metrics.jsonl")
    vrows = read_jsonl(run / "val_metrics.jsonl")
    subtitle = h.e(f"run folder {run.resolve().name}")
    if scene:
        subtitle += " &middot; data " + h.e(Path(scene.get("data_dir", "")).name or scene.get("data_dir", ""))
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
    return h.write(run / "report.html", h.page(f"nerfkit run: {run.resolve().name}", subtitle, sections))




def write_report_or_warn(run_dir: str | Path, log=print) -> Path | None:
    """write_report, for the end of a training command: a report must never cost a finished run, so a
    failure is one line in the log instead of an error."""
    try:
        return write_report(run_dir)
    except Exception as e:  # noqa: BLE001
        log(f"report not written: {e}")
        return None
