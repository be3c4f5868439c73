"""A held-out photo's camera pose fitted to the photo against a splat run's frozen scene (`nerfkit eval --fit-poses
N`, BARF's test-time protocol): the score then measures the scene, not the error of the pose the photo came with.

With the photo I [H, W, 3] and the scene's render R(c2w) [H, W, 3] (every Gaussian held still), the correction xi
= (w, v) [6] of rays/correction.py (w an axis-angle rotation, v a translation in units of the camera's distance
from the scene's centre, so that a turn and a shift of the same size move the centre's image alike) minimises

    E(xi) = |r(xi)|^2,   r(xi) = R(c2w T(xi)) - I   (flattened: the squared error PSNR scores)

by N Levenberg-Marquardt iterations from xi = 0: the Jacobian J [H W 3, 6] of r by central differences (step
FD_STEP, 12 renders), then xi <- xi + d with (J^T J + lambda diag(J^T J)) d = -J^T r, kept when E falls (lambda /
3), else tried again with lambda x 4 (at most MAX_TRIES times). A first-order method crawls here: the orbit about
the scene's centre (a turn and the shift that keeps the centre in view) changes the photo little, so Adam on a
photo the same Gaussians drew (tests/models/splat/test_pose_fit.py's blob) left 0.03-0.47 degrees of a 1.5-degree
error after 400 steps (rates 1e-3 and 3e-3, falling to a tenth), where 10 of these iterations reach float32's floor
(0.01-0.02 degrees).
"""

from __future__ import annotations

from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.gaussians import render_arrays
from nerfkit.models.splat.project import LOWPASS_DILATION
from nerfkit.rays.correction import corrected_composite, corrected_pose, fit_composite

FD_STEP = 1e-3  # radians, and distances from the centre: 0.06 px at a focal length of 60 px
LAMBDA0 = 1e-3
MAX_TRIES = 10


@lru_cache(maxsize=8)
def _residual_fn(width: int, height: int, backend: str, dilation: float, fit_color: bool):
    """r(xi) of the module docstring, jitted, for views of width x height; the render's scene part is moved by
    the photo's colour transform m [3, 4] (rays/correction.corrected_composite; zeros: none), or with fit_color by
    the transform that best maps this render onto the photo (correction.fit_composite, solved afresh at every xi:
    E is then the error left after the best colour, and m is not used)."""

    @jax.jit
    def residual(xi, params, c2w, intr, bg, sh_degree, image, unit, m):
        r = render_arrays(params, corrected_pose(c2w, xi, unit), intr, bg, sh_degree, width, height,
                          backend=backend, depth=False, dilation=dilation)
        if fit_color:
            m = fit_composite(r["rgb"], r["alpha"], bg, image)
        return (corrected_composite(r["rgb"], r["alpha"], bg, m) - image).ravel()

    return residual


def levenberg_marquardt(residual, xi: np.ndarray, iterations: int) -> np.ndarray:
    """xi [6] after `iterations` Levenberg-Marquardt iterations on E = |residual(xi)|^2 from the given xi (module
    docstring: central-difference Jacobians, the damping lambda from LAMBDA0)."""
    xi, lam = np.asarray(xi, np.float64).copy(), LAMBDA0
    r = residual(xi)
    err = r @ r
    basis = FD_STEP * np.eye(6)
    for _ in range(iterations):
        jac = np.stack([(residual(xi + basis[j]) - residual(xi - basis[j])) / (2 * FD_STEP) for j in range(6)], 1)
        a, g = jac.T @ jac, jac.T @ r
        for _ in range(MAX_TRIES):
            step = -np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), g)
            r_new = residual(xi + step)
            if r_new @ r_new < err:
                xi, r, err, lam = xi + step, r_new, r_new @ r_new, lam / 3
                break
            lam *= 4
        else:  # no step lowers the error: a minimum (to float32's precision)
            break
    return xi


def fit_correction(params: dict, c2w, xi, unit: float, intrinsics, width: int, height: int, image, background,
                   sh_degree: int, iterations: int, backend: str = "auto", dilation: float = LOWPASS_DILATION,
                   color=None, fit_color: bool = False) -> np.ndarray:
    """The correction xi [6] (rays/correction.py, translations in units of `unit`) of the view c2w [4, 4] after
    `iterations` Levenberg-Marquardt iterations from xi against the photo image [H, W, 3] (on `background`) and
    the Gaussians `params` (device arrays, splat/gaussians.PARAM_NAMES); color: the photo's colour transform
    [3, 4] where it has one; fit_color: the colour transform fitted to the photo at every step instead
    (_residual_fn)."""
    fn = _residual_fn(int(width), int(height), backend, float(dilation), bool(fit_color))
    args = (params, jnp.asarray(c2w, jnp.float32), jnp.asarray(intrinsics, jnp.float32),
            jnp.asarray(background, jnp.float32), jnp.int32(sh_degree), jnp.asarray(image, jnp.float32)[..., :3],
            jnp.float32(unit), jnp.zeros((3, 4), jnp.float32) if color is None else jnp.asarray(color, jnp.float32))
    return levenberg_marquardt(lambda x: np.asarray(fn(jnp.asarray(x, jnp.float32), *args), np.float64), xi,
                               iterations)


def fit_pose(params: dict, c2w: np.ndarray, intrinsics, width: int, height: int, image: np.ndarray, background,
             sh_degree: int, iterations: int, backend: str = "auto",
             dilation: float = LOWPASS_DILATION, fit_color: bool = False) -> tuple[np.ndarray, dict]:
    """(fitted c2w [4, 4], {"degrees", "shift"}: how far it moved) of the view at c2w [4, 4] (OpenGL, normalised
    frame) seen with intrinsics (fx, fy, cx, cy) at width x height, fitted by `iterations` Levenberg-Marquardt
    iterations (module docstring) to the photo image [H, W, 3] (on `background`) against the Gaussians `params`
    (device arrays, splat/gaussians.PARAM_NAMES); fit_color: the photo's colour fitted alongside (the error left
    after the affine colour map that best fits the render to the photo: `nerfkit eval --fit-colour`)."""
    unit = max(float(np.linalg.norm(np.asarray(c2w, np.float64)[:3, 3])), 1e-6)
    xi = fit_correction(params, c2w, np.zeros(6), unit, intrinsics, width, height, image, background, sh_degree,
                        iterations, backend, dilation, fit_color=fit_color)
    fitted = np.asarray(corrected_pose(jnp.asarray(c2w, jnp.float32), jnp.asarray(xi, jnp.float32), unit), np.float64)
    # how far it moved, from xi itself (|w|, and unit |v| since T's shift is turned by c2w's rotation only)
    return fitted, {"degrees": float(np.degrees(np.linalg.norm(xi[:3]))), "shift": float(unit * np.linalg.norm(xi[3:]))}
