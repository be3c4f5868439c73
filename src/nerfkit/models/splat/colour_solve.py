"""Colour solves during training (--colour-solves N, with the colour transforms on: --appearance on): N times over
the budget (each round's, --pose-rounds), every training photo's colour transform m_k (rays/correction.py) is set
to the one that maps the Gaussians as they stand best onto the photo:

    m_k <- argmin_m |C(R_k, alpha_k, m) - I_k|^2     (correction.fit_composite; closed form: linear in m)

R_k, alpha_k the render of photo k at its (corrected) pose, C = correction.corrected_composite, only the entries of
m that --colour-transform learns free. Adam alone moves a transform only on its photo's visits (one photo a step)
by about its rate (optim.colour_lr), so gains of 15% take most of a short run to learn, and the Gaussians spend
that time fitting photos whose transforms are off. The solves fall where the progress within the run (the round)
crosses

    t_j = j / N,   j = 0 .. N - 1

each after the step that passes it, the first after the first step (the initial points, whose colours are the
photos' mean, already tell each photo's gain apart); between solves Adam goes on moving the transforms with the
Gaussians. A solve costs one render per training photo.
"""

from __future__ import annotations

from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.gaussians import render_arrays
from nerfkit.models.splat.pose_solve import visible_scene
from nerfkit.rays.correction import corrected_pose, fit_composite


def colour_solves_before(progress: float, n: int) -> int:
    """How many of the n solves t_j = j / n (j = 0 .. n - 1) lie before progress t: min(n, ceil(n t)), 0 at t = 0."""
    return 0 if n <= 0 or progress <= 0 else int(min(n, np.ceil(n * progress - 1e-9)))


def colour_solve_due(before: float, after: float, n: int) -> bool:
    """Whether a step that took the progress from `before` to `after` passed a solve t_j (before <= t_j < after):
    the solve then runs after that step."""
    return colour_solves_before(after, n) > colour_solves_before(before, n)


@lru_cache(maxsize=8)
def _fit_fn(width: int, height: int, backend: str, dilation: float, form: str):
    """m [3, 4] (module docstring) of one photo, jitted for views of width x height."""

    @jax.jit
    def fit(params, c2w, xi, intr, bg, sh_degree, image, unit):
        c2w = c2w if xi is None else corrected_pose(c2w, xi, unit)
        r = partial(render_arrays, width=width, height=height, backend=backend, depth=False, dilation=dilation)(
            params, c2w, intr, bg, sh_degree)
        return fit_composite(r["rgb"], r["alpha"], bg, image, form=form)

    return fit


def solve_colours(params: dict, active, poses, images, intrinsics, extent: float, width: int, height: int,
                  background, sh_degree: int, backend: str, dilation: float, form: str) -> np.ndarray:
    """cam_color [V, 3, 4] after one solve (module docstring) of every training photo: poses [V, 4, 4] the photos'
    given poses (moved by params["cam_pose"] [V, 6] where the run refines them; translations in units of
    `extent`), images [V, H, W, 3 or 4] (RGBA views: their colour is already on the background), intrinsics [V, 4];
    active [capacity] the slots in use; form: correction.COLOR_FORMS' key of the entries learned."""
    scene = visible_scene(params, active)
    fit = _fit_fn(int(width), int(height), backend, float(dilation), form)
    xi = params.get("cam_pose")
    bg = jnp.asarray(background, jnp.float32)
    out = [fit(scene, jnp.asarray(poses[k], jnp.float32), None if xi is None else jnp.asarray(xi[k]),
               jnp.asarray(intrinsics[k], jnp.float32), bg, jnp.int32(sh_degree),
               jnp.asarray(images[k], jnp.float32)[..., :3], jnp.float32(extent)) for k in range(len(poses))]
    return keep_mean(np.asarray(jnp.stack(out), np.float64), np.asarray(params["cam_color"], np.float64))


def keep_mean(solved: np.ndarray, before: np.ndarray) -> np.ndarray:
    """The solved transforms [V, 3, 4] moved together so that their mean keeps the one they had before:

        [M_k | o_k] <- A [M_k | o_k],   A = Mb Ms^-1,   M = I + m[:, :3], Ms, Mb the means of solved and before

    A young scene draws every photo too dark (its Gaussians still faint) or too pale alike, which the solve would
    read as a gain common to all; what it tells is each photo's transform relative to the others. (For gains, A is
    per channel the ratio of the mean gains.)"""
    eye = np.eye(3)
    mat_s, mat_b = eye + solved[..., :3], eye + before[..., :3]
    a = mat_b.mean(0) @ np.linalg.inv(mat_s.mean(0))
    moved = np.einsum("ij,vjk->vik", a, np.concatenate([mat_s, solved[..., 3:]], -1))
    return np.concatenate([moved[..., :3] - eye, moved[..., 3:]], -1).astype(np.float32)
