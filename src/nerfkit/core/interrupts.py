"""Ctrl-C and SIGTERM for every verb: one line and an exit status, no traceback, no half-written output.

SIGINT and SIGTERM raise `Interrupted` (a KeyboardInterrupt) in the main thread, so every `with` and `finally`
on the way out runs (a staged output is removed: core/outputs.staged_folder) and `main` prints one line and
exits 128 + the signal's number (130, 143). Training puts its own handlers in place while it runs its steps
(training/stopping.StopFlag: finish the step, save a checkpoint) and these back after; the viewer's serving
loop does so for SIGINT. As those do, the handlers are installed even when the process started with SIGINT
ignored (a background job of a script).

Python drops an exception raised where it cannot propagate (a gc callback, such as the one JAX registers, or
a __del__): it reports it to sys.unraisablehook ("Exception ignored in ...") and goes on. A signal that landed
there was lost: the verb ran to its end and exited 0. The handler puts itself off there (and in an import) and
runs again a moment later (_thread.interrupt_main from another thread); a KeyboardInterrupt dropped all the
same (somewhere not_here does not know) reaches sys.unraisablehook, which raises the signal again the same way.
"""

from __future__ import annotations

import _thread
import contextlib
import gc
import os
import signal
import sys
import threading
import time

SIGNALS = (signal.SIGINT, signal.SIGTERM)
RAISE_AGAIN_SECONDS = 0.02
DEFERRED: set[int] = set()  # signals put off (raise_later), not raised yet
BLOCKED = "NERFKIT_SIGNALS_BLOCKED"  # set in the environment of a process that starts with them blocked


class Interrupted(KeyboardInterrupt):
    """A verb stopped by a signal; `signum` names it."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def raise_interrupted(signum, frame):
    """The handler: raise Interrupted, unless the frame it lands in would drop it or be damaged by it
    (not_here); then a moment later."""
    if not_here(frame):
        DEFERRED.add(signum)
        raise_later(signum)
        return
    DEFERRED.discard(signum)
    raise Interrupted(signum)


def not_here(frame) -> bool:
    """Whether an exception raised in `frame` would be dropped or do harm: on its stack, a gc callback or a
    __del__ (Python drops what they raise; JAX runs one at every collection), or an import (an exception there
    can leave a C extension half made: a Ctrl-C in `import jax` crashed the process with SIGSEGV or SIGABRT)."""
    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code in callbacks or code.co_name == "__del__" or code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def raise_later(signum: int) -> None:
    """Have the main thread's handler for `signum` run again soon: another thread waits RAISE_AGAIN_SECONDS,
    then until the main thread is somewhere not_here allows (polling its frame: the thread takes its turn at
    Python's lock where the main thread runs Python code, which during a collection is the gc callbacks'), then
    interrupts it."""
    main_id = threading.main_thread().ident

    def again():
        time.sleep(RAISE_AGAIN_SECONDS)
        while not_here(sys._current_frames().get(main_id)):
            time.sleep(0.001)
        _thread.interrupt_main(signum)

    threading.Thread(target=again, daemon=True, name="nerfkit-raise-again").start()


def exit_status(e: KeyboardInterrupt) -> tuple[int, str]:
    """(exit status, what stopped the verb in words) for a KeyboardInterrupt: 128 + the signal's number, as a
    shell reports a process a signal ended; a plain KeyboardInterrupt (a second Ctrl-C in training) is SIGINT."""
    signum = getattr(e, "signum", signal.SIGINT)
    return 128 + int(signum), ("aborted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}")


def _unraisable(previous):
    def hook(unraisable):
        exc = unraisable.exc_value
        if isinstance(exc, KeyboardInterrupt):  # a signal raised where it could not propagate: raise it again,
            # a moment later (from here the handler would run at once, inside this hook, and be dropped again)
            signum = getattr(exc, "signum", signal.SIGINT)
            DEFERRED.add(signum)
            raise_later(signum)
            return
        previous(unraisable)

    return hook


def install() -> tuple[dict, object] | None:
    """SIGINT / SIGTERM raise Interrupted from now on, and one dropped where it could not propagate is raised
    again. (The earlier handlers, the earlier hook) to put back; None outside the main thread, where no signal
    handler can be set."""
    old = {}
    for sig in SIGNALS:
        try:
            old[sig] = signal.signal(sig, raise_interrupted)
        except ValueError:  # not the main thread
            return None
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _unraisable(previous_hook)
    return old, previous_hook


@contextlib.contextmanager
def interrupts_raise():
    """Within: install(); the earlier handlers and hook are put back on leaving."""
    saved = install()
    try:
        yield
    finally:
        if saved is not None:
            old, sys.unraisablehook = saved
            for sig, handler in old.items():
                signal.signal(sig, handler)


def block_across_exec(environ: dict) -> None:
    """Before the process replaces itself (hugepages.restart_with_huge_pages): block SIGINT and SIGTERM, so that
    one sent while the new process starts waits (a blocked signal stays pending across execve) until its
    handlers are in place, and mark `environ` (the new process's) so that it unblocks them
    (unblock_if_restarted)."""
    signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    if DEFERRED:  # one is on its way (raise_later) and would not survive execve: stop here instead
        unblock()
        raise Interrupted(min(DEFERRED))
    environ[BLOCKED] = "1"


def unblock() -> None:
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)


def unblock_if_restarted() -> None:
    """In a process block_across_exec started, with the handlers in place: let a signal held since arrive."""
    if os.environ.pop(BLOCKED, None):
        unblock()
