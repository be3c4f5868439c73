"""Argument parsing shared by every verb: tyro with its errors as one line, and flags read early."""

from __future__ import annotations

import contextlib
import io

import tyro

from nerfkit.core.errors import ConfigError


def one_line(text: str, prog: str) -> str:
    """tyro's parse error (boxed, or plain where there is no terminal) as one line: the message, its first
    suggestion, and where the help is."""
    sections, cur = [], []
    for raw in text.splitlines():
        if raw.lstrip().startswith(("╭", "╰")):  # the box's title and bottom
            continue
        if raw.strip().startswith("│"):  # in the box: one space of margin inside its sides
            line = raw.strip().strip("│").rstrip()
            line = line[1:] if line.startswith(" ") else line
        else:  # the plain layout: the title one space in, the text two
            line = raw.rstrip()
            line = line[2:] if line.startswith("  ") else line.lstrip()
        if not line.strip() or set(line.strip()) <= set("─-╭╮╰╯ "):  # a rule: the box's or the plain layout's
            if cur and set(line.strip()) <= set("─- ") and line.strip():
                sections.append(cur)
                cur = []
            continue
        cur.append(line)
    if cur:
        sections.append(cur)
    if len(sections) > 1 and len(sections[0]) == 1 and ":" not in sections[0][0]:
        sections = sections[1:]  # the plain layout (no box: a terminal without one) puts the title on a line of its own
    if not sections:
        return f"invalid arguments; see {prog} --help"
    first = sections[0]
    if first[0].startswith("Missing from"):
        names = [x.strip() for x in first[1:] if x.startswith("    ") and not x.startswith("     ")]
        msg = "missing " + ", ".join(names or [" ".join(x.strip() for x in first[1:])])
    elif first[0].startswith("Unrecognized options"):
        msg = first[0]
    else:
        msg = " ".join(x.strip() for x in first)
    for sec in sections[1:]:
        if sec[0].strip().startswith("Perhaps you meant") and len(sec) > 1:
            msg += f"; perhaps you meant {sec[1].split()[0]}"
    return f"{msg.rstrip('.')}; see {prog} --help"


def parse(cls, argv: list[str], prog: str, default=None):
    """tyro.cli, with a parse error turned into one ConfigError line (exit 1 in main) instead of a box."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return tyro.cli(cls, args=argv, prog=prog, default=default)
    except SystemExit as e:
        if e.code in (0, None):
            raise
        raise ConfigError(one_line(err.getvalue(), prog)) from None


def flag_value(argv: list[str], flag: str) -> str | None:
    """The value given to `flag` ("--flag V" or "--flag=V"), read before tyro parses argv; ConfigError where it
    is given several different values (tyro would take the last, a reader of the first would disagree)."""
    values = [argv[k + 1] if a == flag else a.split("=", 1)[1] for k, a in enumerate(argv)
              if (a == flag and k + 1 < len(argv)) or a.startswith(flag + "=")]
    if len(set(values)) > 1:
        raise ConfigError(f"{flag} given {len(values)} times ({', '.join(values)}); give it once")
    return values[0] if values else None


