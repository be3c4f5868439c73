"""`nerfkit eval --fit-colour` (evaluation/colour.py): the colour map is fitted on the photo's left half and only
the right half is scored, so a photo at another exposure scores as its render deserves, and what differs on the
right half (the part scored) is not fitted away."""

import jax.numpy as jnp
import numpy as np

from nerfkit.core.metrics import psnr
from nerfkit.evaluation.colour import colour_fitted, left_half
from nerfkit.rays.correction import corrected_composite

H, W = 12, 16
GAIN = np.array([[0.15, 0.0, 0.0, 0.02], [0.0, 0.1, 0.0, 0.0], [0.0, 0.0, -0.1, 0.03]], np.float32)


def render_and_photo(seed: int = 0):
    """A render (rgb over a white background, opacity) and the photo it becomes under the transform GAIN."""
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.5, 1.0, (H, W)).astype(np.float32)
    bg = (1.0, 1.0, 1.0)
    rgb = (rng.uniform(0.1, 0.7, (H, W, 3)) * alpha[..., None] + (1 - alpha[..., None])).astype(np.float32)
    photo = np.asarray(corrected_composite(jnp.asarray(rgb), jnp.asarray(alpha), jnp.asarray(bg), jnp.asarray(GAIN)))
    return {"rgb": rgb, "opacity": alpha}, photo, bg


def test_left_half_is_the_fitted_columns():
    mask = left_half(3, 7)
    assert mask.shape == (3, 7) and mask[:, :3].all() and not mask[:, 3:].any()


def test_a_photo_at_another_exposure_scores_as_its_render_deserves():
    render, photo, bg = render_and_photo()
    fitted, row = colour_fitted(render, photo, bg)
    assert row["psnr"] > 50.0 and row["ssim"] > 0.999
    assert row["colour_fit"]["psnr_unfitted"] < 30.0  # the gain alone costs this much (27 dB)
    assert np.allclose(row["colour_fit"]["transform"], GAIN, atol=5e-3)
    assert np.allclose(fitted, np.clip(photo, 0, 1), atol=2e-3)


def test_only_the_right_half_is_scored_and_only_the_left_half_fitted():
    render, photo, bg = render_and_photo()
    wrong_right = photo.copy()
    wrong_right[:, W // 2:] = 0.5  # the scored half no longer matches
    _, row = colour_fitted(render, wrong_right, bg)
    assert np.allclose(row["colour_fit"]["transform"], GAIN, atol=5e-3)  # fitted on the left half alone
    assert row["psnr"] < 25.0
    assert row["psnr"] == psnr(np.asarray(colour_fitted(render, photo, bg)[0])[:, W // 2:], wrong_right[:, W // 2:])
    wrong_left = photo.copy()
    wrong_left[:, : W // 2] = 0.5  # the fitted half is wrong: the map fitted there spoils the right half
    _, row = colour_fitted(render, wrong_left, bg)
    assert row["psnr"] < 25.0
