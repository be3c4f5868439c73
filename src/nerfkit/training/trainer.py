"""Training: the run loop (the jit-compiled step is step.py) and the run folder it writes.

Run folder layout (see README):

    config.json          resolved config          scene.json      camera/image facts
    metrics.jsonl        step, loss, psnr, lr, elapsed (train)
    val_metrics.jsonl    step, psnr, elapsed, per-view PSNR (validation)
    plots/               train_loss.png, train_psnr.png, val_psnr.png
    val/step_XXXXXXX/    view_K.png (ground truth | render | depth), view_K_depth.npy
    checkpoints/         ckpt_XXXXXXXX.msgpack (the newest `keep_ckpts`)
"""

from __future__ import annotations

import json
import math
import shlex
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.config import Config, validate
from nerfkit.core.errors import NerfkitError
from nerfkit.core.metrics import mse_to_psnr
from nerfkit.core.viz import background_rgb, plot_curves, read_jsonl
from nerfkit.models.registry import build_model
from nerfkit.rays.correction import run_poses
from nerfkit.render.images import make_renderer
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training import parallel
from nerfkit.training.callbacks import Checkpoints, ProgressBar
from nerfkit.training.flags import describe_budget, describe_model
from nerfkit.training.setup import (
    clear_run,
    load_splits,
    refuse_earlier_run,
    refuse_unfit_run_folder,
    with_triangulated_points,
)
from nerfkit.training.step import init_state, make_optimizer, make_train_step
from nerfkit.training.stopping import StopFlag
from nerfkit.training.validation import evenly_spaced, render_validation, validation_factor, validation_views


@dataclass
class TrainResult:
    run_dir: Path
    step: int
    val_psnr: float | None
    steps_per_second: float
    interrupted: bool


@dataclass
class Loop:
    """What the training loop carries from step to step (Trainer.run)."""

    step: int  # steps done
    first_step: int  # the step this session started from (0, or the resumed checkpoint's)
    elapsed0: float  # training seconds before this session (a resumed run's)
    start: float  # time.perf_counter() when this session's loop started
    deadline: float  # perf_counter time of --max-minutes (inf without)
    pending: list = field(default_factory=list)  # (step, device metrics) not yet logged
    rays: list = field(default_factory=list)  # (rays per step, samples per ray) of logged rows (models that report them)
    last_val: float | None = None  # the last validation's mean PSNR
    last_val_step: int = -1
    val_gate: float = 0.0  # no periodic validation before this clock time (keeps validation <= val_max_fraction)

    def elapsed(self, now: float | None = None) -> float:
        """Training seconds of the run at perf_counter time `now` (default: now)."""
        return self.elapsed0 + (time.perf_counter() if now is None else now) - self.start


class Trainer:
    def __init__(self, data_dir: str | Path, run_dir: str | Path, cfg: Config, resume: bool = False,
                 progress: bool = True, overwrite: bool = False):
        """Load the data, resolve cfg from it, build the model and say the plan. `overwrite`: a fresh run into a
        folder that holds an earlier run's files removes them first (otherwise it is refused). Flags a user
        typed are checked before (setup.refuse_given, called by the CLI). Callbacks (self.callbacks,
        callbacks.py) join the loop: the progress bar and the checkpoints by default, the viewer's with
        nerfkit train --viewer."""
        self.cfg = validate(cfg)
        self.data_dir = Path(data_dir)
        self.run_dir = Path(run_dir)
        self.resume = resume
        self.progress = progress
        self.ckpt_dir = self.run_dir / "checkpoints"
        refuse_unfit_run_folder(self.run_dir)
        self.overwrite = refuse_earlier_run(self.run_dir, resume, overwrite)
        say = tqdm.write if progress else (lambda *_: None)
        self.capture, self.train_data, self.val_data, self.cfg = load_splits(self.data_dir, cfg, progress, say)
        self._set_up_model(say)
        self._say_plan(say)
        self.callbacks: list = [ProgressBar(progress), Checkpoints(self.cfg.train.ckpt_every)]  # callbacks.Callback

    def _set_up_model(self, say) -> None:
        """The model of self.cfg, the device mesh its data-parallel split runs on (none for whole views, which
        train on one device), the optimiser and the image renderer; says what the model is and how it splits."""
        cfg = self.cfg
        self.model = build_model(cfg)
        split = self.model.supports.parallel  # what the devices split (make_train_step)
        self.mesh = None if split == "views" else parallel.data_mesh(parallel.mesh_devices(cfg.train.devices))
        self.primary = parallel.is_primary()  # process 0 of a multi-process run writes the run folder
        if split == "rays":
            parallel.check_batch(self.model.rays_per_step, self.mesh)
        elif split == "samples":
            parallel.check_batch(cfg.sampler.max_samples, self.mesh, "--max-samples")
        say(f"model: {describe_model(cfg)}")
        if split == "views":  # whole views, one per step, on one device (Gaussian splats)
            if self.model.supports.points and self.model.wants_points(self.capture):
                self.capture = with_triangulated_points(self.capture, cfg.data.train_split, say)
            self.model.bind_data(self.capture, self.train_data, log=say)
        else:
            say(parallel.describe(self.model.rays_per_step, self.mesh, split, cfg.sampler.max_samples))
        self.optimizer, self.schedule = make_optimizer(cfg, self.model)
        self.renderer = make_renderer(self.model, cfg.train.chunk)

    def _say_plan(self, say) -> None:
        """Pick the views periodic validation renders (self.val_ids) and say them and the budget."""
        cfg, spec_val = self.cfg, self.cfg.data.val_split
        self.val_ids = evenly_spaced(len(self.val_data), cfg.train.val_views)
        vd = self.val_data
        self.val_factor = 1 if vd.sizes is not None else validation_factor(vd.width, vd.height)
        small = "" if self.val_factor == 1 else (
            f" at {vd.width // self.val_factor}x{vd.height // self.val_factor} (1/{self.val_factor} of the photos' "
            f"size, so that validating costs a small share of the budget)")
        whole = "" if len(self.val_ids) == len(self.val_data) and self.val_factor == 1 else (
            f"; nerfkit eval {shlex.quote(str(self.run_dir))} --split {shlex.quote(spec_val)} scores all "
            f"{len(self.val_data)} at full size")
        say(f"validation: {validation_views(self.val_ids, len(self.val_data), spec_val)}{small}{whole}")
        say(f"budget: {describe_budget(cfg)}")

    # -- run folder -------------------------------------------------------------------
    def _write_run_files(self):
        if not self.primary:
            return
        if self.overwrite:
            clear_run(self.run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        (self.run_dir / "config.json").write_text(self.cfg.to_json())
        td = self.train_data
        scene = {"data_dir": str(self.data_dir.resolve()), "format": td.format, "height": td.height, "width": td.width,
                 "focal": td.focal, "camera": td.cameras[0].to_json(), "n_train": len(td), "n_val": len(self.val_data),
                 "masks": td.has_masks, "transform": td.transform.tolist(), "scale": td.scale,
                 "train_poses": td.poses.tolist()}
        (self.run_dir / "scene.json").write_text(json.dumps(scene, indent=2))

    def _append(self, name: str, row: dict):
        if not self.primary:
            return
        with open(self.run_dir / name, "a") as f:
            f.write(json.dumps(row) + "\n")

    def _truncate_logs(self, step: int):
        """After a resume, drop log rows past the restored step (written after the checkpoint)."""
        if not self.primary:
            return
        for name in ("metrics.jsonl", "val_metrics.jsonl"):
            rows = [r for r in read_jsonl(self.run_dir / name) if r.get("step", 0) <= step]
            (self.run_dir / name).write_text("".join(json.dumps(r) + "\n" for r in rows))

    def plot(self):
        rows = read_jsonl(self.run_dir / "metrics.jsonl")
        vrows = read_jsonl(self.run_dir / "val_metrics.jsonl")
        plots = self.run_dir / "plots"
        steps = [r["step"] for r in rows]
        what = self.model.loss_name
        plot_curves({"train": (steps, [r["loss"] for r in rows])}, plots / "train_loss.png", "step", f"loss ({what})",
                    "Training loss", logy=True)
        plot_curves({"train": (steps, [r["psnr"] for r in rows])}, plots / "train_psnr.png", "step", "PSNR (dB)",
                    "Training PSNR", min_span=1.0)
        plot_curves({"val": ([r["step"] for r in vrows], [r["psnr"] for r in vrows])}, plots / "val_psnr.png", "step",
                    "PSNR (dB)", f"Validation PSNR ({len(vrows[-1]['views']) if vrows else 0} views)", min_span=1.0)

    def validate(self, state, step: int, elapsed: float) -> float:
        """Render the validation views, save them beside ground truth, log mean PSNR and the seconds it took
        (process 0 only)."""
        t0 = time.perf_counter()
        state = parallel.host_copy(state)
        val = self.val_data  # pose refinement: the views' poses moved with the training rig (correction.py)
        if "cam_pose" in state["params"]:
            val = replace(val, poses=run_poses(state["params"], self.train_data.poses, val.poses))
        scores = render_validation(self.renderer, state["params"], state["aux"], val, self.val_ids,
                                   self.val_factor, self.run_dir / "val" / f"step_{step:07d}",
                                   background_rgb(self.cfg.data.background))
        mean = float(np.mean(scores))
        self._append("val_metrics.jsonl", {"step": step, "psnr": mean, "elapsed": round(elapsed, 2),
                                           "seconds": round(time.perf_counter() - t0, 2), "views": self.val_ids,
                                           "per_view": [round(s, 3) for s in scores]})
        self.plot()
        return mean

    def save(self, state, step: int, elapsed: float):
        if not self.primary:
            return
        full = dict(parallel.host_copy(state), elapsed=np.float64(elapsed))
        ckpt_lib.save_checkpoint(self.ckpt_dir, step, full, self.cfg.to_dict()["field"], self.cfg.train.keep_ckpts)

    # -- the loop ---------------------------------------------------------------------
    def _restore(self, state):
        """(step, elapsed, state) from the newest checkpoint when resuming (before anything in the run folder is
        written: a bad checkpoint changes nothing), else (0, 0.0, state)."""
        path = ckpt_lib.latest_checkpoint(self.ckpt_dir) if self.resume else None
        if path is None:
            return 0, 0.0, state, None
        target = dict(state, elapsed=np.float64(0))
        step, restored = ckpt_lib.restore_checkpoint(path, target, self.cfg.to_dict()["field"])
        elapsed = float(restored.pop("elapsed"))
        return step, elapsed, jax.tree_util.tree_map(jnp.asarray, restored), path

    def _log(self, pending: list, elapsed: float) -> dict:
        """Check the pending steps' metrics for non-finite ones (NerfkitError after max_bad_steps in a row) and
        append the last one's row to metrics.jsonl (loss and PSNR: of its batch; a model that trains on one
        view per step: the mean over the pending steps); returns that row."""
        t = self.cfg.train
        for s, mm in pending:
            if bool(mm["finite"]):
                self._bad_streak = 0
                continue
            self._bad_streak += 1
            tqdm.write(f"step {s}: non-finite loss or gradient ({float(mm['loss'])}); update skipped")
            if self._bad_streak >= t.max_bad_steps:
                raise NerfkitError(f"stopping: {self._bad_streak} non-finite steps in a row (last at step {s}); the "
                                   f"last good checkpoint in {self.ckpt_dir} is intact. Try a lower --lr.")
        s, mm = pending[-1]
        loss, mse = float(mm["loss"]), float(mm["mse"])
        if self.model.supports.parallel == "views":  # one view per step: the mean over the logged steps
            good = [m for _, m in pending if bool(m["finite"])] or [mm]
            loss, mse = (float(np.mean([float(m[k]) for m in good])) for k in ("loss", "mse"))
        row = {"step": s, "loss": loss, "psnr": float(mse_to_psnr(mse)),
               "lr": float(self.schedule(s)), "elapsed": round(elapsed, 3)}
        row.update({k: float(v) for k, v in mm.items() if k not in ("loss", "mse", "finite")})
        self._append("metrics.jsonl", row)
        pending.clear()
        return row

    def run(self) -> TrainResult:
        """Train from step 0, or from the newest checkpoint when resuming, until --max-steps, --max-minutes or a
        stop signal (Ctrl-C: a checkpoint is saved); logs, validates and checkpoints on the way."""
        step, elapsed0, state = self._begin()
        images, poses, state = parallel.replicate(
            (jnp.asarray(self.train_data.images), jnp.asarray(self.train_data.poses), state), self.mesh)
        step_fn = make_train_step(self.model, self.optimizer, self.train_data, self.cfg, self.mesh)
        t = self.cfg.train
        start = time.perf_counter()
        loop = Loop(step, step, elapsed0, start, start + 60 * t.max_minutes if t.max_minutes else math.inf)
        self._bad_streak = 0
        for c in self.callbacks:
            c.begin(self, loop, state)
        with StopFlag() as stop:
            state, interrupted, reason = self._loop(loop, state, step_fn, images, poses, stop)
            self._end(loop, state, interrupted, reason)
        # A signal after the last step (during its validation or the final save) stops what the caller runs next.
        return self._result(loop, interrupted or stop.signal_name is not None)

    def _begin(self):
        """(step, elapsed, state) to start from (_restore), once the run folder's files are written and, when
        resuming, its logs cut back to that step."""
        step, elapsed0, state, path = self._restore(init_state(self.model, self.optimizer, self.cfg.train.seed))
        self._write_run_files()
        if path is not None:
            self._truncate_logs(step)
            tqdm.write(f"resumed from {path} at step {step}")
        elif self.resume:
            self._truncate_logs(0)  # rows of a run that died before its first checkpoint
            tqdm.write(f"no checkpoint in {self.ckpt_dir}: starting from step 0")
        return step, elapsed0, state

    def _loop(self, loop: Loop, state, step_fn, images, poses, stop: StopFlag):
        """Run steps until a limit or a stop signal: (state, interrupted, the limit reached in words)."""
        t = self.cfg.train
        while loop.step < t.max_steps:
            if parallel.agree(time.perf_counter() >= loop.deadline):
                return state, False, f"--max-minutes {t.max_minutes:g} reached"
            state, m = step_fn(state, jnp.int32(loop.step), images, poses)
            jax.block_until_ready(m)  # keeps the bar's rate and ETA honest (steps are compute-bound)
            loop.step += 1
            loop.pending.append((loop.step, m))
            for c in self.callbacks:
                c.after_step(self, loop, state)
            if loop.step % t.log_every == 0 or loop.step == t.max_steps or stop.signal_name:
                self._log_pending(loop)
            if parallel.agree(bool(stop.signal_name)):
                return state, True, f"--max-steps {t.max_steps} reached"
            self._validate_on_schedule(loop, state)
        return state, False, f"--max-steps {t.max_steps} reached"

    def _log_pending(self, loop: Loop) -> None:
        """Log the pending steps (_log), note the row's rays per step, and hand the row to the callbacks."""
        row = self._log(loop.pending, loop.elapsed())
        loop.rays += [(row["rays"], row["samples_per_ray"])] if "rays" in row else []
        for c in self.callbacks:
            c.after_log(self, loop, row)

    def _validate_on_schedule(self, loop: Loop, state) -> None:
        """Validate every --val-every steps (process 0), but not before loop.val_gate: after a validation that
        took v seconds, the next waits v (1 - f) / f seconds, so validation takes at most --val-max-fraction f
        of the wall time."""
        t = self.cfg.train
        if loop.step % t.val_every == 0 and time.perf_counter() >= loop.val_gate and self.primary:
            v0 = time.perf_counter()
            loop.last_val = self.validate(state, loop.step, loop.elapsed(v0))
            loop.last_val_step = loop.step
            took = time.perf_counter() - v0
            loop.val_gate = time.perf_counter() + took * (1 - t.val_max_fraction) / t.val_max_fraction
            tqdm.write(f"step {loop.step}: val PSNR {loop.last_val:.2f} dB ({took:.1f} s)")

    def _end(self, loop: Loop, state, interrupted: bool, reason: str) -> None:
        """After the loop: log what is pending (the last step is always in metrics.jsonl), validate the last
        step unless interrupted or just done, and end the callbacks (the last checkpoint is theirs)."""
        step = loop.step
        if loop.pending:  # the last step is always in metrics.jsonl (summaries quote it)
            self._log_pending(loop)
        elapsed = loop.elapsed()
        if not interrupted:
            tqdm.write(f"{reason} at step {step}")
        if not interrupted and loop.last_val_step != step and step > 0 and self.primary:
            loop.last_val = self.validate(state, step, elapsed)
            tqdm.write(f"step {step}: val PSNR {loop.last_val:.2f} dB")
        for c in self.callbacks:
            c.end(self, loop, state, interrupted)

    def _result(self, loop: Loop, interrupted: bool) -> TrainResult:
        """The plots (when no validation drew them), the closing lines, and the TrainResult."""
        t, step = self.cfg.train, loop.step
        if self.primary and (not read_jsonl(self.run_dir / "val_metrics.jsonl") or interrupted):
            self.plot()
        run_time = time.perf_counter() - loop.start
        sps = (step - loop.first_step) / run_time if run_time > 0 else 0.0
        if loop.rays:
            rays, spr = np.mean([r for r, _ in loop.rays]), np.mean([s for _, s in loop.rays])
            how = (f"as many of the {t.batch_rays} drawn as fit" if self.model.supports.marching else
                   f"{self.model.rays_per_step} x {spr:.0f} samples fill")
            tqdm.write(f"rays per step: {rays:.0f} on average, {spr:.0f} samples per ray ({how} --max-samples "
                       f"{self.cfg.sampler.max_samples})")
        if interrupted:
            tqdm.write(f"stopped at step {step}; checkpoint saved in {self.ckpt_dir}. Resume with:\n"
                       f"  nerfkit train {shlex.quote(str(self.data_dir))} --out {shlex.quote(str(self.run_dir))} --resume")
        return TrainResult(self.run_dir, step, loop.last_val, sps, interrupted)
