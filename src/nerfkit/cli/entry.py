"""The `nerfkit` command (and `python -m nerfkit`): Ctrl-C and SIGTERM handled from its first line.

Importing the CLI (cli/main.py and what it imports) takes a fraction of a second a Ctrl-C can land in, so
this module imports only the handlers (core/interrupts.py), installs them for good, and then the CLI.
"""

from __future__ import annotations

import os
import sys

from nerfkit.core.interrupts import exit_status, install, unblock_if_restarted


def command_line() -> None:
    """Install the handlers, then run `main` on sys.argv and exit with its status (128 + N for signal N; 0 when
    the reader of its output went away)."""
    install()
    try:
        unblock_if_restarted()
        from nerfkit.cli.main import main

        status = main()
        sys.stdout.flush()  # (a reader that went away shows here, not as Python exits)
    except KeyboardInterrupt as e:
        status, words = exit_status(e)
        print(f"nerfkit: {words}", file=sys.stderr)
    except BrokenPipeError:  # the reader of our output went away (`nerfkit --help | head -1`): not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        status = 0
    sys.exit(status)
