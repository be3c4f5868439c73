"""Periodic validation during training (trainer.Trainer.validate): which held-out views, at what size, and
rendering, scoring and saving them. `nerfkit eval` (evaluation/) scores every view at full size afterwards.

Photos larger than VAL_MAX_PIXELS are validated shrunk by an integer factor f (f x f pixels averaged, the
camera scaled by 1/f), so that a validation costs a small share of the budget: a 1368x770 photo is validated
at 456x256.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.core.metrics import psnr
from nerfkit.core.viz import colorize_renders, comparison, save_png
from nerfkit.data.capture import SceneData
from nerfkit.data.images import area_downscale

VAL_MAX_PIXELS = 1 << 17


def validation_factor(width: int, height: int, max_pixels: int = VAL_MAX_PIXELS) -> int:
    """The smallest integer f >= 1 with (width // f) (height // f) <= max_pixels."""
    f = 1
    while (width // f) * (height // f) > max_pixels and min(width, height) // (f + 1) >= 1:
        f += 1
    return f


def evenly_spaced(n: int, k: int) -> list[int]:
    """k (at most n) indices spread evenly over 0 .. n - 1, ends included."""
    k = min(k, n)
    return sorted({int(round(x)) for x in np.linspace(0, n - 1, k)})


def validation_views(ids: list[int], n: int, spec: str) -> str:
    """Which views periodic validation renders, in words: "4 of 9 views of test (0, 3, 5, 8), evenly spaced"."""
    shown = ", ".join(map(str, ids[:12])) + (", ..." if len(ids) > 12 else "")
    return (f"all {n} views of {spec}" if len(ids) == n else
            f"{len(ids)} of {n} views of {spec} ({shown}), evenly spaced")


def render_validation(renderer, params, aux, data: SceneData, ids: list[int], factor: int, out_dir: Path,
                      background) -> list[float]:
    """PSNR of each view `ids` of `data` rendered at 1/factor of its size (against the photo shrunk alike),
    saved as out_dir/view_KKK.png (ground truth | render | depth) and view_KKK_depth.npy."""
    scores, renders, gts = [], [], []
    for k in ids:
        cam = data.cameras[k]
        if factor > 1:
            cam = cam.scaled(1.0 / factor, cam.width // factor, cam.height // factor)
        gts.append(area_downscale(data.image(k), factor))
        renders.append(renderer.render_camera(params, aux, data.poses[k], cam))
        scores.append(psnr(renders[-1]["rgb"], gts[-1]))
    depth_imgs, (lo, hi) = colorize_renders(renders, background)
    for k, gt, r, depth_img, score in zip(ids, gts, renders, depth_imgs, scores):
        save_png(out_dir / f"view_{k:03d}.png", comparison(gt, r["rgb"], depth_img, lo / data.scale, hi / data.scale,
                                                           score, background=background))
        np.save(out_dir / f"view_{k:03d}_depth.npy", r["depth"].astype(np.float32), allow_pickle=False)
    return scores
