"""The splat optimiser's per-group rates (models/splat/optim.py)."""

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.models.splat.optim import LearningRates, adam_step, colour_lr, init_state, make_optimizers, pose_lr


def test_the_colour_rate_falls_log_linearly_to_a_tenth():
    lrs = LearningRates(cam_color=2e-3)
    got = [colour_lr(t, lrs) for t in (-0.5, 0.0, 0.5, 1.0, 1.5)]
    assert got == pytest.approx([2e-3, 2e-3, 2e-3 / np.sqrt(10), 2e-4, 2e-4], rel=1e-6)


def test_the_pose_rate_waits_for_the_warm_up_ramps_over_as_long_and_falls_to_a_tenth():
    lrs = LearningRates(cam_pose=1e-4, pose_warmup=0.25)
    got = [pose_lr(t, lrs) for t in (0.0, 0.2, 0.25, 0.375, 0.5, 0.75, 1.0)]
    assert got == pytest.approx([0.0, 0.0, 0.0, 5e-5, 1e-4, 1e-4 / np.sqrt(10), 1e-5], rel=1e-6)
    assert pose_lr(0.0, LearningRates(cam_pose=1e-4, pose_warmup=0.0)) == pytest.approx(1e-4)  # no warm-up


def test_adam_moves_the_colour_transforms_by_the_rate_it_is_given():
    """Adam's first step under a constant gradient moves each entry by its rate (bias-corrected), so the
    move reads the rate the optimiser used: lr_color where given, the configured cam_color where None."""
    lrs = LearningRates(cam_color=1e-3)
    params = {"means": jnp.zeros((4, 3)), "cam_color": jnp.zeros((2, 3, 4))}
    opts = {k: v for k, v in make_optimizers(lrs, 1.0, corrections=("cam_color",)).items() if k in params}
    grads = {"means": jnp.zeros((4, 3)), "cam_color": jnp.ones((2, 3, 4))}
    for lr_color, moved in ((None, 1e-3), (2.5e-4, 2.5e-4), (colour_lr(1.0, lrs), 1e-4)):
        new, _ = adam_step(opts, init_state(opts, params), grads, params, 1e-4, None, lr_color)
        np.testing.assert_allclose(np.asarray(new["cam_color"]), -moved, rtol=1e-3)
