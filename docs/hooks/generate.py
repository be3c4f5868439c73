"""MkDocs hooks: what the site shows is generated from the code and the benchmark records, not copied.

- `<!-- nerfkit-help: VERB [KIND] -->` becomes the output of `nerfkit VERB [KIND] --help`.
- `<!-- nerfkit-measurements -->` becomes a table of every benchmarks/results/*.json: what it measured,
  the command and commit that wrote it, and its top-level figures.
- `<!-- nerfkit-readme -->` (the home page) becomes README.md, its links made relative to docs/.
- The pictures in benchmarks/results/ are published under results/.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"


def on_files(files, config):
    for path in sorted(RESULTS.glob("*")):
        if path.suffix.lower() in (".png", ".jpg", ".jpeg", ".gif", ".svg"):
            files.append(File.generated(config, f"results/{path.name}", abs_src_path=str(path)))
    return files


def _help(args: list[str]) -> str:
    from nerfkit.cli.main import main

    os.environ["COLUMNS"] = "100"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            main([*args, "--help"])
        except SystemExit:
            pass
    return out.getvalue().rstrip()


def _figures(record: dict) -> str:
    """The record's top-level numbers and short strings, as `key: value` items."""
    items = []
    for key, value in record.items():
        if key in ("provenance", "what", "data", "command"):
            continue
        if isinstance(value, bool) or isinstance(value, (int, float)):
            items.append(f"{key}: {value:g}" if isinstance(value, float) else f"{key}: {value}")
        elif isinstance(value, str) and len(value) <= 40:
            items.append(f"{key}: {value}")
    return "; ".join(items[:10]) or "(nested: see the file)"


def _measurements() -> str:
    rows = ["| record | what | written by | commit | figures |", "| --- | --- | --- | --- | --- |"]
    for path in sorted(RESULTS.glob("*.json")):
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(record, dict):
            continue
        prov = record.get("provenance") or {}
        what = str(record.get("what", "")).replace("|", "/")
        command = str(prov.get("command", "")).replace("|", "/")
        commit = str(prov.get("commit", ""))[:10] + (" (dirty)" if prov.get("dirty") else "")
        rows.append(f"| `{path.name}` | {what} | `{command}` | {commit} | {_figures(record).replace('|', '/')} |")
    return "\n".join(rows)


def _readme() -> str:
    """README.md as the site's home page: links into docs/ and benchmarks/results/ made site-relative."""
    text = (ROOT / "README.md").read_text()
    text = text.replace("](docs/", "](").replace("](benchmarks/results/", "](results/")
    manual = "The manual is a MkDocs site in `docs/` (read the Markdown on GitHub, or build it:\n"
    if manual not in text:
        raise ValueError("docs/hooks/generate.py: README's sentence about the manual changed; update _readme")
    return text.replace(manual, "This site is built from `docs/` (")


def on_page_markdown(markdown, page, config, files):
    if "<!-- nerfkit-readme -->" in markdown:
        markdown = markdown.replace("<!-- nerfkit-readme -->", _readme())
    markdown = re.sub(r"<!-- nerfkit-help: ([a-z -]+?) -->",
                      lambda m: "```text\n" + _help(m.group(1).split()) + "\n```", markdown)
    return markdown.replace("<!-- nerfkit-measurements -->", _measurements())
