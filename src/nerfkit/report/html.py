"""The pieces every static HTML report is made of: inline CSS, escaped text, tables, figures
linked by relative paths (so a report folder opens from disk, copies and zips), and the page.
A report has no scripts, fonts or anything else from the network."""

from __future__ import annotations

import datetime as _dt
import html
import json
import os
from pathlib import Path
from urllib.parse import quote

from PIL import Image

from nerfkit.core.outputs import replace_with

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

def e(x) -> str:
    return html.escape(str(x), quote=True)


def rel_url(path: Path, base: Path) -> str:
    """A relative, percent-encoded URL from the folder `base` to `path`."""
    rel = os.path.relpath(Path(path).resolve(), Path(base).resolve())
    return quote(Path(rel).as_posix())


def image_size(path: Path) -> tuple[int, int] | None:
    try:
        with Image.open(path) as im:
            return im.size
    except Exception:  # unreadable or not an image: no size hint
        return None


def display_width(natural: int) -> int:
    if natural >= MIN_DISPLAY_WIDTH:
        return natural
    return natural * -(-MIN_DISPLAY_WIDTH // natural)  # integer upscale, crisp pixels


def img(path: Path, base: Path, alt: str, caption: str = "", max_width: int | None = None) -> str:
    url = rel_url(path, base)
    size = image_size(path)
    attrs = ""
    if size:
        w = display_width(size[0])
        if max_width:
            w = min(w, max_width)
        attrs = f' width="{w}"'
    cap = f"<figcaption>{caption}</figcaption>" if caption else ""
    return f'<figure><a href="{e(url)}"><img src="{e(url)}" alt="{e(alt)}"{attrs}></a>{cap}</figure>'


def video(path: Path, base: Path, caption: str = "", width: int | None = None) -> str:
    url = rel_url(path, base)
    w = f' width="{display_width(width)}"' if width else ""
    cap = f'<figcaption>{caption} (<a href="{e(url)}">{e(Path(path).name)}</a>)</figcaption>'
    return (f'<figure><video controls muted loop autoplay playsinline preload="auto"{w} src="{e(url)}">'
            f'</video>{cap}</figure>')


def link(path: Path, base: Path, text: str | None = None) -> str:
    return f'<a href="{e(rel_url(path, base))}">{e(text if text is not None else Path(path).name)}</a>'


def table(header: list[str], rows: list[list[str]], numeric: set[int] = frozenset(),
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


def page(title: str, subtitle: str, sections: list[tuple[str, str, str]]) -> str:
    """sections: (anchor id, heading, body html)."""
    nav = " ".join(f'<a href="#{e(a)}">{e(h)}</a>' for a, h, body in sections if body)
    body = "".join(f'<section id="{e(a)}"><h2>{e(h)}</h2>{b}</section>' for a, h, b in sections if b)
    stamp = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
        f"<title>{e(title)}</title><style>{CSS}</style></head><body>"
        f"<header><h1>{e(title)}</h1><p>{subtitle}</p></header>"
        f"<main><nav>{nav}</nav>{body}"
        f'<p class="muted">written by nerfkit on {e(stamp)}; a static page: all links are relative, '
        "nothing is loaded from the network.</p></main></body></html>\n"
    )


def write(path: Path, text: str) -> Path:
    return replace_with(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def minutes(seconds: float | None) -> str:
    if seconds is None:
        return "n/a"
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def fmt(x, digits: int = 2) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def read_json(path: Path) -> dict | None:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return None


# -- one run --------------------------------------------------------------------------------------

