"""Stopping a training loop cleanly: SIGINT / SIGTERM finish the current step and save a checkpoint."""

from __future__ import annotations

import os
import signal
import sys


class StopFlag:
    """SIGINT / SIGTERM ask the loop to stop after the current step; a second SIGINT aborts."""

    def __init__(self):
        self.signal_name: str | None = None
        self._old = {}

    def __enter__(self):
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[sig] = signal.signal(sig, self._handle)
            except ValueError:  # not the main thread: no signal handling
                pass
        return self

    def _handle(self, signum, frame):
        if self.signal_name is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.signal_name = signal.Signals(signum).name
        msg = f"{self.signal_name} received: finishing this step, saving a checkpoint (Ctrl-C again to abort)\n"
        try:  # os.write, not print: a handler that prints while the loop prints hits a reentrant-write error
            os.write(sys.stderr.fileno(), msg.encode())
        except (OSError, ValueError, AttributeError):  # stderr replaced (e.g. captured): best effort
            pass

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
