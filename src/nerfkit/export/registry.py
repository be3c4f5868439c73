"""The exporters, by name (`nerfkit export NAME RUN_DIR`): adding one is a module defining EXPORTER (an
`Exporter`, below) and one line in EXPORTERS. The CLI (cli/export.py), the run folder's records and the
run report (report/run.py) read this table; none of them lists the exporters itself.

An exporter declares:

    name      the verb's kind: nerfkit export NAME
    summary   one line for `nerfkit export --help`
    args      a dataclass of its flags (tyro parses it: field docstrings are the help), the first one
              `run_dir` (positional)
    accepts   supports -> bool: the runs it exports, by what their model supports (models/base.Supports)
    needs     what an accepted run has, in words (the refusal of any other run names it)
    outputs   the files it writes by default, under RUN/exports/ (its record export_NAME.json beside them)
    export    (args, given) -> record: does the work; `given` is the set of flags typed ("--every"), for
              refusing a flag that the other values make moot. The record is a dict with at least "file"
              (what was written) and "picture" (a PNG under RUN/exports/ that shows it)
    wrote     record -> the CLI's line about what was written
    facts     record -> the run report's caption of it
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

from nerfkit.core.errors import ConfigError

EXPORTERS: dict[str, str] = {  # name -> the module that defines its EXPORTER (imported when used)
    "mesh": "nerfkit.export.mesh",
    "pointcloud": "nerfkit.export.pointcloud",
    "cameras": "nerfkit.export.cameras",
    "splat": "nerfkit.export.splat",
}


@dataclass(frozen=True)
class Exporter:
    name: str
    summary: str
    args: type
    accepts: Callable[[Any], bool]
    needs: str
    outputs: tuple[str, ...]
    export: Callable[[Any, set], dict]
    wrote: Callable[[dict], str]
    facts: Callable[[dict], str]


def exporter(name: str) -> Exporter:
    """The exporter called `name`; ConfigError naming the ones there are otherwise."""
    if name not in EXPORTERS:
        raise ConfigError(f"export needs a kind: nerfkit export {'|'.join(EXPORTERS)} RUN_DIR (got {name!r})")
    return importlib.import_module(EXPORTERS[name]).EXPORTER


def check_accepts(ex: Exporter, run_dir, supports, title: str) -> None:
    """ConfigError unless `ex` exports runs whose model supports `supports` (its `accepts`)."""
    if not ex.accepts(supports):
        others = [n for n in EXPORTERS if n != ex.name and exporter(n).accepts(supports)]
        raise ConfigError(f"{run_dir}: export {ex.name} needs {ex.needs}; this run's {title} model has none "
                          f"(this run exports with: {', '.join('nerfkit export ' + n for n in others)})")
