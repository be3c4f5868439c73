"""cli/parsing.one_line: tyro's parse errors as one line naming the flag, in both of tyro's layouts (a box on a
terminal; a title line and rules where there is none, as under pytest or in a CI log)."""

import pytest

from nerfkit.cli.args import EvalArgs
from nerfkit.cli.parsing import one_line, parse
from nerfkit.core.errors import ConfigError

BOXED = """╭─ Unrecognized options ──────────────────────╮
│ Unrecognized options: --no-progress         │
│ ─────────────────────────────────────────── │
│ For full helptext, run nerfkit eval --help  │
╰─────────────────────────────────────────────╯
"""
PLAIN = (" Unrecognized options                         \n -------------------------------------------- \n"
         "  Unrecognized options: --no-progress         \n  --------------------------------------------\n"
         "  For full helptext, run nerfkit eval --help  \n                                              \n")


@pytest.mark.parametrize("text", [BOXED, PLAIN])
def test_both_layouts_name_the_option(text):
    assert one_line(text, "nerfkit eval") == "Unrecognized options: --no-progress; see nerfkit eval --help"


@pytest.mark.parametrize("argv,said", [(["/tmp", "--split", "test", "--no-progress"],
                                        "Unrecognized options: --no-progress; see nerfkit eval --help"),
                                       (["--split", "test"], "missing PATH; see nerfkit eval --help"),
                                       (["/tmp", "--every", "x"], "Error parsing --every: invalid literal"),
                                       (["/tmp", "--splitt", "x"], "perhaps you meant --split")])
def test_tyros_own_errors_become_one_line(argv, said, capsys):
    """What tyro writes with pytest capturing the output (the plain layout) names the flag, not the title."""
    with pytest.raises(ConfigError) as e:
        parse(EvalArgs, argv, "nerfkit eval")
    assert said in str(e.value) and "\n" not in str(e.value), str(e.value)
