"""Density control as objects that carry their own settings (gsplat's `Strategy`): the training step
(train.py) asks its strategy, never which one it is.

    regularizer(params, active) -> scalar       added to the photometric loss (jittable)
    after_adam(key, params, stats, g_means2d, radii, active, lr_means, width, height) -> (params, stats)
                                                 inside the jitted step, after Adam: MCMC's position noise,
                                                 classic's gradient statistics (densify.accumulate)
    control(params, active, stats, rng, extent, width, resets_done) -> (params, active, stats, touched)
                                                 on the host (numpy params), when `window.due(step, t)`:
                                                 the round that moves, clones, splits or prunes Gaussians;
                                                 touched: the slots written (their Adam moments are reset)
    reset_every                                  steps between opacity resets inside the window (0: none)
    reset_opacity                                the opacity they clamp to

MCMC (mcmc.py) and Classic (densify.py) are the two strategies; NoControl trains the initial Gaussians
as they are. `strategy_named` builds one from its --strategy name with its default settings.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat import densify as classic
from nerfkit.models.splat import mcmc


@dataclass(frozen=True)
class Window:
    """When density control runs: every `every` steps from step `start` while the progress t < `until`
    (3DGS: every 100 steps from 500 to 15k of 30k; MCMC: to 25k)."""

    every: int = 100
    start: int = 500
    until: float = 0.8

    def open(self, progress: float) -> bool:
        return progress < self.until

    def due(self, step: int, progress: float) -> bool:
        """Whether a round runs after step `step` (1-based count of steps done) at progress t."""
        return step >= self.start and step % self.every == 0 and self.open(progress)


@dataclass(frozen=True)
class NoControl:
    """No density control: the initial Gaussians train as they are."""

    name = "none"
    window: Window = field(default_factory=Window)
    reset_every = 0
    reset_opacity = 0.0

    def regularizer(self, params: dict, active) -> jnp.ndarray:
        return jnp.float32(0.0)

    def after_adam(self, key, params, stats, g_means2d, radii, active, lr_means, width: int, height: int):
        return params, stats

    def control(self, params: dict, active: np.ndarray, stats: dict, rng, extent: float, width: int,
                resets_done: int):
        return params, active, stats, np.zeros(0, np.int64)


@dataclass(frozen=True)
class MCMC(NoControl):
    """3DGS-MCMC (mcmc.py): opacity and scale regularisers, SGLD noise on the positions after every Adam step,
    and every round dead Gaussians relocated onto live ones, then growth by `grow_rate` into unused slots."""

    name = "mcmc"
    opacity_reg: float = mcmc.OPACITY_REG
    scale_reg: float = mcmc.SCALE_REG
    noise_lr: float = mcmc.NOISE_LR
    grow_rate: float = 0.05

    def regularizer(self, params: dict, active) -> jnp.ndarray:
        return mcmc.regularizer(params, self.opacity_reg, self.scale_reg, active)

    def after_adam(self, key, params, stats, g_means2d, radii, active, lr_means, width: int, height: int):
        noise = mcmc.position_noise(key, params, lr_means, self.noise_lr)
        return dict(params, means=params["means"] + jnp.where(active[:, None], noise, 0.0)), stats

    def control(self, params: dict, active: np.ndarray, stats: dict, rng, extent: float, width: int,
                resets_done: int):
        params, touched = mcmc.relocate(params, active, rng)
        if not active.all():
            params, active, grown = mcmc.grow(params, active, rng, self.grow_rate)
            touched = np.union1d(touched, grown)
        return params, active, stats, touched


@dataclass(frozen=True)
class Classic(NoControl):
    """Classic 3DGS (densify.py): view-space gradient statistics, then every round clone, split and prune by
    `schedule`'s thresholds; opacity resets every schedule.reset_every steps (0: none)."""

    name = "classic"
    schedule: classic.ClassicSchedule = field(default_factory=classic.ClassicSchedule)

    @property
    def reset_every(self) -> int:
        return self.schedule.reset_every

    @property
    def reset_opacity(self) -> float:
        return self.schedule.reset_opacity

    def after_adam(self, key, params, stats, g_means2d, radii, active, lr_means, width: int, height: int):
        return params, classic.accumulate(stats, g_means2d, radii, width, height)

    def control(self, params: dict, active: np.ndarray, stats: dict, rng, extent: float, width: int,
                resets_done: int):
        params, active, touched = classic.densify(params, active, stats, extent, rng, self.schedule, width,
                                                  resets_done > 0)
        return params, active, classic.zero_stats(len(active)), touched


STRATEGIES = {s.name: s for s in (MCMC, Classic, NoControl)}


def strategy_named(name: str, window: Window | None = None):
    """The strategy called `name` (mcmc, classic or none) with its default settings (and `window`, if given)."""
    if name not in STRATEGIES:
        raise ValueError(f"strategy must be one of {', '.join(STRATEGIES)}, got {name!r}")
    return STRATEGIES[name]() if window is None else STRATEGIES[name](window=window)
