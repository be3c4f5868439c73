"""Ctrl-C and SIGTERM for every verb (core/interrupts.py): the signal stops the verb where it lands, even where
Python drops exceptions (a gc callback such as JAX's) or in an import, and outlives the huge-page restart; the
command prints one line, exits 128 + N and leaves no staged output."""

from __future__ import annotations

import gc
import importlib
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from nerfkit.core.interrupts import Interrupted, exit_status, interrupts_raise
from nerfkit.cli.main import main
from nerfkit.data.procedural.scene import make_scene


def _spin(seconds: float) -> None:
    """Ordinary Python code running for `seconds`, collecting garbage as it goes."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        gc.collect()
        time.sleep(0.005)


def test_a_signal_dropped_in_a_gc_callback_is_raised_again():
    """A SIGINT handled inside a gc callback (where JAX has one) raised there and was dropped by Python ("Exception
    ignored in ..."): the verb ran on. It is raised again in ordinary code."""
    fired = []

    def callback(phase, info):
        if phase == "start" and not fired:
            fired.append(1)
            signal.raise_signal(signal.SIGINT)  # its handler runs here, inside the callback
            _spin(0)  # (a line of Python code, where the handler runs)

    gc.callbacks.append(callback)
    try:
        with interrupts_raise(), pytest.raises(Interrupted) as e:
            _spin(5)
    finally:
        gc.callbacks.remove(callback)
    assert fired and e.value.signum == signal.SIGINT and exit_status(e.value) == (130, "aborted")


def test_a_signal_in_an_import_waits_for_the_import_to_finish(tmp_path, monkeypatch):
    """An exception raised in the middle of an import can leave a C extension half made (a Ctrl-C in `import jax`
    crashed the process); the signal is raised once the import is done."""
    (tmp_path / "slow_module_for_interrupts.py").write_text(textwrap.dedent("""
        import signal, time
        signal.raise_signal(signal.SIGTERM)
        t = time.monotonic()
        while time.monotonic() < t + 0.2:
            pass
        FINISHED = True
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    with interrupts_raise(), pytest.raises(Interrupted) as e:
        importlib.import_module("slow_module_for_interrupts")
        _spin(5)
    assert sys.modules.pop("slow_module_for_interrupts").FINISHED
    assert e.value.signum == signal.SIGTERM and exit_status(e.value) == (143, "stopped by SIGTERM")


def test_the_handlers_are_put_back():
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM), sys.unraisablehook
    with interrupts_raise():
        assert signal.getsignal(signal.SIGTERM) is not before[1]
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM), sys.unraisablehook) == before


def test_a_signal_sent_while_the_process_restarts_reaches_the_new_one(tmp_path):
    """The huge-page restart replaces the process (execve); a SIGTERM sent before the new one has its handlers
    used to kill it (or print a traceback from its start-up). Blocked across the exec, it arrives once they are
    in place."""
    script = textwrap.dedent("""
        import os, signal, sys
        from nerfkit.core import interrupts
        if sys.argv[1] == "first":
            env = dict(os.environ)
            interrupts.block_across_exec(env)
            os.kill(os.getpid(), signal.SIGTERM)  # pending: blocked
            os.execve(sys.executable, [sys.executable, __file__, "second"], env)
        interrupts.install()
        try:
            interrupts.unblock_if_restarted()
            for _ in range(1000):
                sum(range(1000))
            print("missed")
        except interrupts.Interrupted as e:
            print("caught", e.signum, os.environ.get(interrupts.BLOCKED))
    """)
    (tmp_path / "restart.py").write_text(script)
    out = subprocess.run([sys.executable, str(tmp_path / "restart.py"), "first"], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and out.stdout.split() == ["caught", str(int(signal.SIGTERM)), "None"], out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_a_write_leaves_nothing_and_says_one_line(tmp_path, sig):
    """`nerfkit make-scene` stopped while it writes (its staged folder exists): exit 128 + N, one line naming the
    verb and the signal, no traceback, and neither the staged folder nor the output is left."""
    out = tmp_path / "scene"
    staged = tmp_path / ".scene.incomplete"
    proc = subprocess.Popen([sys.executable, "-m", "nerfkit", "make-scene", str(out), "--size", "64", "--n-train",
                             "40", "--n-val", "2", "--n-test", "2"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 120
        while not staged.exists() and proc.poll() is None and time.monotonic() < end:
            time.sleep(0.005)
        assert staged.exists(), "make-scene never staged its output"
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    words = "aborted" if sig == signal.SIGINT else "stopped by SIGTERM"
    assert proc.returncode == 128 + sig, (stdout, stderr)
    assert stderr.strip().splitlines() == [f"nerfkit make-scene: {words}"], stderr
    assert not staged.exists() and not out.exists()


def test_a_signal_after_the_last_step_stops_an_experiment(tmp_path, monkeypatch):
    """A Ctrl-C that lands after a run's last step (its final validation or checkpoint) used to be forgotten:
    `experiment` went on to its next model. The run reports it as interrupted."""
    from nerfkit.training.trainer import Trainer

    end = Trainer._end

    def end_then_interrupted(self, *args):
        end(self, *args)
        signal.raise_signal(signal.SIGINT)  # training's handler (StopFlag) takes it

    monkeypatch.setattr(Trainer, "_end", end_then_interrupted)
    data = make_scene(tmp_path / "scene", size=16, n_train=4, n_val=1, n_test=1)
    code = main(["experiment", "pe-ablation", str(data), "--out", str(tmp_path / "exp"), "--preset", "tiny",
                 "--max-steps", "2", "--no-progress"])
    assert code == 130
    assert len([p for p in (tmp_path / "exp").rglob("config.json")]) == 1  # the first model's run, no second


def test_a_keyboard_interrupt_python_drops_elsewhere_is_raised_again():
    """Where not_here cannot tell (a weakref callback), the dropped KeyboardInterrupt reaches sys.unraisablehook,
    which raises the signal again."""
    import weakref

    class Thing:
        pass

    def callback(ref):
        raise Interrupted(signal.SIGTERM)

    thing = Thing()
    ref = weakref.ref(thing, callback)
    with interrupts_raise(), pytest.raises(Interrupted) as e:
        del thing  # the callback runs here; Python drops what it raises
        _spin(5)
    assert ref() is None and e.value.signum == signal.SIGTERM


@pytest.mark.parametrize("unbuffered", ["1", ""])
@pytest.mark.parametrize("argv", [["--help"], ["train", "--help"]])
def test_a_reader_that_goes_away_is_not_an_error(argv, unbuffered):
    """`nerfkit --help | head -1`: the reader closes the pipe; the command exits 0 without a traceback (the top-level
    usage printed one), whether its output is buffered or not."""
    r, w = os.pipe()
    os.close(r)  # the reader is gone before anything is written
    env = {**os.environ, "PYTHONUNBUFFERED": unbuffered}
    out = subprocess.run([sys.executable, "-m", "nerfkit", *argv], stdout=w, stderr=subprocess.PIPE, text=True,
                         env=env, timeout=120)
    os.close(w)
    assert out.returncode == 0 and out.stderr == "", out.stderr
