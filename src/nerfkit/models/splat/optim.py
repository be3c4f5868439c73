"""Adam with per-parameter learning rates (optax), and Adam-state surgery for density control.

Learning rates, Adam eps = 1e-15 (3DGS's, Kerbl et al. 2023, in brackets where they differ):

    means       lr(t) = exp((1 - t) log(3.2e-4 E) + t log(3.2e-6 E)),  t = progress in [0, 1]   [1.6e-4, 1.6e-6]
    sh_dc       2e-2 [2.5e-3]     sh_rest  2e-2 / 20 [2.5e-3 / 20]
    opacity     5e-2              log_scales  1e-2 [5e-3]          quats  1e-3

3DGS's rates are set for 30k steps from SfM points whose colours are already right. A 10-minute CPU
run takes 1-7k steps, and Adam moves a parameter by about its rate a step, so at 3DGS's colour rate a
mid-grey start (a Blender scene's points) needs ~700 consistent steps to reach white or black. Colour x8,
positions x2 and scales x2 were chosen on lego (seed protocol, held-out val[50:75], a fixed number of steps;
CHANGELOG.md): 28.96 -> 31.71 dB after 1200 steps, 33.96 -> 35.20 after 6000 (colour x16: 30.46 at 1200;
positions x4: 31.97 and 35.05; opacity x2 on top of that: 32.05 and 34.66); maryrose's held-out photos, 2000
steps: 23.22 -> 24.85 dB. Both are masked objects whose Gaussians start grey (the hull). Photos without masks
(core/config --colour-lr unset) learn colour at 3DGS's COLOUR_LR_PHOTOS instead: on buddha (11 photos of a head in
a room, SfM points, 3 minutes at 342 px, training seeds 0-2, one sitting) 19.88 dB held out against 19.25 at 2e-2,
ahead with each seed (benchmarks/results/buddha_colour_lr_seed*_cli.json); maryrose from its own SfM points (masks,
3 minutes at 432 px, seeds 0-1) keeps 2e-2: 24.48 against 23.66 at 2.5e-3 (CHANGELOG.md).

E is the scene extent: 1.1 x the largest distance of a training camera centre from their
mean (3DGS's "cameras_extent"), so the position step is relative to the scene's size.
3DGS decays the means' rate over 30k steps; here t is the fraction of the run done (steps or
wall clock), so the decay ends with the run whatever its length.

Per-photo corrections (rays/correction.py; --appearance, --pose-refine), groups of their own:

    cam_color   lr(t) = R 10^-t (the colour transforms, [V, 3, 4]): log-linear from R to R/10, R = 3e-3 by default
                (--colour-transform-lr). Each step trains one photo, so a photo's transform moves only on its
                visits, by several times the rate (Adam's moments decay in between) and towards that view's
                passing error; held at 1e-3 to the end they kept wandering (0.25% with no gains to find) and the
                scene paid for it: on the forward-facing corrections capture at 128 px (exact poses, 2000 steps,
                held-out right halves with their colour fitted) 39.98 dB against 40.75 without transforms, and
                with gains up to 15% 39.57; decayed, 40.81 and 40.42 (CHANGELOG.md). R: with gains of up to 15%
                all around the objects at 320 px (exact poses, 2000 steps, training seed 1) 3e-3 learns them
                within 0.004 and scores 33.54 dB against the exact capture's 33.49, where 1e-3 leaves 0.008 and
                32.89, 1e-2 33.01; facing forward at 128 px 3e-3 is ahead of 1e-3 with each of three seeds, and
                on buddha's held-out photos by 0.22 dB on the mean of three (docs: Per-photo corrections).
    cam_pose    lr(t) = 1e-4 ramp(t), ramp 0 until t = W (--pose-warmup, 0.1: the first views are too blurred to
                pull a pose the right way), rising linearly to 1 at t = 2W, then log-linearly to 0.1 at t = 1.
                Procedural unbounded captures, 35 photos at 64 px integrating their pixels, poses 0.96 degrees
                off, 2000 steps (one run each; training's validation on the 5 exact held-out photos): all around
                the objects 5e-4 left 0.44-0.47 degrees and 24.6-25.1 dB (three runs), 1e-4 0.52 degrees and
                25.8 dB; facing one way (forward) 5e-4 turned the poses further off (1.16 degrees, 19.9 dB;
                21.7 dB without refinement), 2e-4 0.76 degrees and 22.8 dB, 1e-4 0.68 and 24.5 dB.

Each parameter group has its own optax.inject_hyperparams(optax.adam) so that the means'
rate can be set every step from the host (a traced scalar, no recompilation).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np
import optax

ADAM_EPS = 1e-15


@dataclass(frozen=True)
class LearningRates:
    """Per-group Adam learning rates (means: initial and final factors of the scene extent)."""

    means_init: float = 3.2e-4
    means_final: float = 3.2e-6
    sh_dc: float = 2e-2
    sh_rest: float = 2e-2 / 20
    opacity: float = 5e-2
    log_scales: float = 1e-2
    quats: float = 1e-3
    cam_color: float = 3e-3
    cam_pose: float = 1e-4
    pose_warmup: float = 0.1  # progress before which the poses stay put (then a ramp of the same length)


COLOUR_LR_PHOTOS = 2.5e-3  # sh_dc's rate for photos without masks (3DGS's; module docstring)
CORRECTIONS = ("cam_color", "cam_pose")  # the per-photo groups (their leading axis is the photo, not the Gaussian)


def colour_lr_for(photos: bool) -> float:
    """--colour-lr unset: COLOUR_LR_PHOTOS for photos without masks, else the LearningRates default (docstring)."""
    return COLOUR_LR_PHOTOS if photos else LearningRates().sh_dc


def colour_rates(lrs: LearningRates, colour: float | None, transform: float | None = None) -> LearningRates:
    """lrs with the colour groups' rates set from `colour` (sh_dc = colour, sh_rest = colour / 20, 3DGS's ratio)
    and the colour transforms' (cam_color) from `transform`; None keeps lrs' own."""
    lrs = lrs if colour is None else replace(lrs, sh_dc=colour, sh_rest=colour / 20)
    return lrs if transform is None else replace(lrs, cam_color=transform)


def means_lr(progress: float, extent: float, lrs: LearningRates = LearningRates()) -> float:
    """Log-linear decay of the means' rate from means_init E to means_final E as progress goes 0 -> 1."""
    t = float(np.clip(progress, 0.0, 1.0))
    return float(extent * np.exp((1 - t) * np.log(lrs.means_init) + t * np.log(lrs.means_final)))


def pose_lr(progress: float, lrs: LearningRates = LearningRates()) -> float:
    """The pose corrections' rate at progress t: 0 until pose_warmup, a linear ramp to cam_pose at twice that,
    then log-linear down to 0.1 cam_pose at t = 1 (module docstring)."""
    t, w = float(np.clip(progress, 0.0, 1.0)), lrs.pose_warmup
    if t < w:
        return 0.0
    if t < 2 * w:
        return lrs.cam_pose * (t - w) / w
    return float(lrs.cam_pose * np.exp(np.log(0.1) * (t - 2 * w) / max(1.0 - 2 * w, 1e-9)))


def colour_lr(progress: float, lrs: LearningRates = LearningRates()) -> float:
    """The colour transforms' rate at progress t: cam_color 10^-t, log-linear down to a tenth at t = 1."""
    return float(lrs.cam_color * 0.1 ** float(np.clip(progress, 0.0, 1.0)))


def make_optimizers(lrs: LearningRates, extent: float, eps: float = ADAM_EPS, corrections=()) -> dict:
    """{group: optax transformation}: Adam (epsilon `eps`, 3DGS: 1e-15) with an injectable learning rate per group;
    `corrections` adds groups of CORRECTIONS (Adam's usual epsilon 1e-8: their gradients are not 3DGS's tiny
    per-Gaussian ones)."""
    rates = {"means": lrs.means_init * extent, "log_scales": lrs.log_scales, "quats": lrs.quats,
             "opacity": lrs.opacity, "sh_dc": lrs.sh_dc, "sh_rest": lrs.sh_rest}
    extra = {k: optax.inject_hyperparams(optax.adam)(learning_rate=getattr(lrs, k), eps=1e-8) for k in corrections}
    return {k: optax.inject_hyperparams(optax.adam)(learning_rate=v, eps=eps) for k, v in rates.items()} | extra


def init_state(opts: dict, params: dict) -> dict:
    """{group: optax state} for parameters {group: array}."""
    return {k: opts[k].init(params[k]) for k in opts}


def adam_step(opts: dict, state: dict, grads: dict, params: dict, lr_means, lr_pose=None,
              lr_color=None) -> tuple[dict, dict]:
    """One Adam step of every group (jittable); the means' rate is set to lr_means (traced scalar) first, the
    pose corrections' to lr_pose and the colour transforms' to lr_color where they are trained (None: kept).

    Returns (new params, new state)."""
    state = dict(state)
    for group, lr in (("means", lr_means), ("cam_pose", lr_pose), ("cam_color", lr_color)):
        if group in state and lr is not None:
            hyper = {**state[group].hyperparams, "learning_rate": jnp.asarray(lr, jnp.float32)}
            state[group] = state[group]._replace(hyperparams=hyper)
    new_params, new_state = dict(params), {}
    for k in opts:
        upd, new_state[k] = opts[k].update(grads[k], state[k], params[k])
        new_params[k] = optax.apply_updates(params[k], upd)
    return new_params, new_state


def reset_rows(state: dict, rows: np.ndarray, n: int) -> dict:
    """The optimiser state with Adam's moments zeroed for the Gaussians `rows` (int [M]).

    Every array leaf whose leading axis has length n (the moments mu, nu of each group) gets
    rows set to 0; scalars (step count, learning rates) are kept. Used when density control
    overwrites Gaussians, so the new ones do not inherit their slot's momentum."""
    rows = jnp.asarray(rows, jnp.int32)

    def zero(leaf):
        if isinstance(leaf, jax.Array) and leaf.ndim >= 1 and leaf.shape[0] == n:
            return leaf.at[rows].set(0)
        return leaf

    return jax.tree_util.tree_map(zero, state)
