"""`nerfkit export KIND RUN_DIR`: one exporter per call, each with its own flags (export/registry.py lists
them; each exporter's module defines its flags as a dataclass, parsed by tyro like the other verbs')."""

from __future__ import annotations

from pathlib import Path

from nerfkit.cli.parsing import parse
from nerfkit.core.errors import ConfigError
from nerfkit.export.files import refuse_own_input
from nerfkit.export.registry import EXPORTERS, check_accepts, exporter


def typed_flags(argv: list[str]) -> set[str]:
    """The flags typed in argv, without their values: {"--every", "--no-snap"}."""
    return {a.split("=", 1)[0] for a in argv if a.startswith("--")}


def cmd_export(argv: list[str]) -> int:
    kinds = "|".join(EXPORTERS)
    if not argv or argv[0] not in EXPORTERS:
        if argv and argv[0] in ("-h", "--help"):
            print(f"usage: nerfkit export {{{','.join(EXPORTERS)}}} RUN_DIR [--out FILE] ...  "
                  f"(nerfkit export KIND --help for its options)")
            for name in EXPORTERS:
                print(f"  {name:<11} {exporter(name).summary}")
            return 0
        got = f" (got {argv[0]!r})" if argv else ""
        raise ConfigError(f"export needs a kind: nerfkit export {kinds} RUN_DIR{got}")
    ex, rest = exporter(argv[0]), argv[1:]
    a = parse(ex.args, rest, f"nerfkit export {ex.name}")
    run_dir = Path(a.run_dir)
    refuse_own_input(getattr(a, "out", None), run_dir, getattr(a, "data", None))
    if (run_dir / "config.json").is_file():  # refuse a run it cannot export before loading it
        from nerfkit.models.registry import method_class
        from nerfkit.run.folder import RunFolder

        method = method_class(RunFolder(run_dir).config())
        check_accepts(ex, run_dir, method.supports, method.title)
    rec = ex.export(a, typed_flags(rest))
    print(ex.wrote(rec))
    picture = run_dir / "exports" / rec["picture"]
    if (run_dir / "report.html").is_file():
        from nerfkit.report.run import write_report

        print(f"picture: {picture}, also in {write_report(run_dir)}")
    else:
        print(f"picture: {picture} (and in the run report: nerfkit report {run_dir})")
    return 0
