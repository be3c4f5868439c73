"""Scoring held-out photos whose colour the scene cannot know (`nerfkit eval --fit-colour`).

A photo's exposure and white balance are its own: a run with a colour transform or an appearance embedding per
training photo renders a held-out view with their mean, which a photo taken at another exposure does not match.
NeRF-W's protocol (Martin-Brualla et al. 2021) fits the photo's appearance on the left half of the photo and scores
the right half; here the appearance is the affine colour map of rays/correction.py, fitted in closed form
(correction.fit_composite: least squares, the error is linear in it), so it applies to every method alike:

    m = argmin_m  sum_{p in left} |C(R_p, m) - I_p|^2,    C(R, m) = (I + m[:, :3]) f + alpha m[:, 3] + (1 - alpha) b

with R the render (its scene part f = R - (1 - alpha) b over the background b, opacity alpha) and I the photo
[H, W, 3]; left: the columns x < W // 2. The score is PSNR / SSIM of C(R, m) (clipped to [0, 1]) against I on the
columns x >= W // 2 only: the 12 numbers fitted never see the pixels they are scored on.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from nerfkit.core.metrics import psnr, ssim
from nerfkit.rays.correction import corrected_composite, fit_composite

COLOUR_NOTE = ("each view's colour fitted to its photo (an affine colour map, least squares on the photo's left "
               "half; --fit-colour) and scored on the right half only (NeRF-W's protocol for photos whose exposure "
               "no training photo shares)")


def left_half(height: int, width: int) -> np.ndarray:
    """[H, W] bool: True on the columns x < W // 2, where the colour is fitted."""
    return np.broadcast_to(np.arange(width) < width // 2, (height, width))


def colour_fitted(render: dict, image: np.ndarray, background, form: str = "affine") -> tuple[np.ndarray, dict]:
    """(the render's rgb [H, W, 3] mapped by the colour transform fitted on the photo's left half, clipped to [0, 1];
    its scores: {"psnr", "ssim"} of the right half, and "colour_fit": {"transform": m [3, 4] as lists,
    "psnr_unfitted": the right half's PSNR before the map}) of a render (rgb [H, W, 3], opacity [H, W]) and its
    photo image [H, W, 3] on `background` (an RGB triple); form: the entries of the map fitted
    (correction.COLOR_FORMS; `eval` fits the whole affine map)."""
    rgb, alpha = jnp.asarray(render["rgb"], jnp.float32), jnp.asarray(render["opacity"], jnp.float32)
    image = np.asarray(image, np.float32)[..., :3]
    bg = jnp.asarray(background, jnp.float32)
    h, w = image.shape[:2]
    m = fit_composite(rgb, alpha, bg, jnp.asarray(image), jnp.asarray(left_half(h, w), jnp.float32), form)
    fitted = np.clip(np.asarray(corrected_composite(rgb, alpha, bg, m)), 0.0, 1.0)
    right = slice(w // 2, None)
    return fitted, {"psnr": psnr(fitted[:, right], image[:, right]), "ssim": ssim(fitted[:, right], image[:, right]),
                    "colour_fit": {"transform": np.asarray(m, np.float64).round(6).tolist(),
                                   "psnr_unfitted": psnr(np.asarray(render["rgb"])[:, right], image[:, right])}}
