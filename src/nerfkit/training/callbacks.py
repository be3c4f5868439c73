"""What joins the training loop from outside it: the progress bar, the checkpoints and (nerfkit train --viewer)
the live viewer are callbacks in `Trainer.callbacks`, called in list order:

    begin(trainer, loop, state)        once, before the first step of this session (state: the resumed one)
    after_step(trainer, loop, state)   after every step (loop.step: the steps done)
    after_log(trainer, loop, row)      after a metrics.jsonl row is written (row: that row)
    end(trainer, loop, state, interrupted)   once, after the last step's log and validation

`loop` is the trainer's Loop (step, first_step, deadline, last_val, ...). A callback overrides the hooks it needs.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

from tqdm.auto import tqdm


class Callback:
    """A training-loop callback: every hook does nothing unless overridden."""

    def begin(self, trainer, loop, state) -> None:
        pass

    def after_step(self, trainer, loop, state) -> None:
        pass

    def after_log(self, trainer, loop, row: dict) -> None:
        pass

    def end(self, trainer, loop, state, interrupted: bool) -> None:
        pass


@dataclass
class ProgressBar(Callback):
    """A tqdm bar of steps (on stderr), made after the first step so that its rate and ETA leave the compilation
    out; it shows the last logged loss and PSNR and the last validation PSNR. Under a time budget its end moves to
    where the time runs out at the measured step rate. enabled=False: nothing is shown."""

    enabled: bool = True
    bar: tqdm | None = None
    compiled_at: float | None = None  # perf_counter time the first step (with its compilation) finished

    def begin(self, trainer, loop, state) -> None:
        if self.enabled and loop.step < trainer.cfg.train.max_steps:
            tqdm.write("compiling the training step (a one-off; the next run of this model starts faster)...")

    def after_step(self, trainer, loop, state) -> None:
        if self.bar is None:
            self.compiled_at = time.perf_counter()
            self.bar = tqdm(total=trainer.cfg.train.max_steps, initial=loop.step, disable=not self.enabled,
                            dynamic_ncols=True, desc="train", unit="step", file=sys.stderr, mininterval=1.0)
        else:
            self.bar.update(1)

    def after_log(self, trainer, loop, row: dict) -> None:
        if self.bar is None:
            return
        now = time.perf_counter()
        if math.isfinite(loop.deadline) and loop.step > loop.first_step + 1:
            rate = (loop.step - loop.first_step - 1) / max(now - self.compiled_at, 1e-9)
            self.bar.total = min(trainer.cfg.train.max_steps, loop.step + int(rate * max(loop.deadline - now, 0.0)))
        self.bar.set_postfix(loss=f"{row['loss']:.4f}", psnr=f"{row['psnr']:.2f}",
                             val=f"{loop.last_val:.2f}" if loop.last_val is not None else "-")

    def end(self, trainer, loop, state, interrupted: bool) -> None:
        if self.bar is not None:
            self.bar.close()


@dataclass
class Checkpoints(Callback):
    """A checkpoint every `every` steps and one at the end (also after Ctrl-C), through trainer.save (the newest
    --keep-ckpts are kept)."""

    every: int
    saved: int = -1  # the step of the last checkpoint written

    def after_step(self, trainer, loop, state) -> None:
        if loop.step % self.every == 0:
            self._save(trainer, loop, state)

    def end(self, trainer, loop, state, interrupted: bool) -> None:
        if self.saved != loop.step:
            self._save(trainer, loop, state)

    def _save(self, trainer, loop, state) -> None:
        trainer.save(state, loop.step, loop.elapsed())
        self.saved = loop.step
