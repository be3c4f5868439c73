"""Rendering a splat run's views: SplatRenderer, what SplatModel.renderer() returns (the image renderer of
render/images.make_renderer, the viewer, evaluation and the exports hold one per model)."""

from __future__ import annotations

import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.models.splat.depth import median_depth
from nerfkit.models.splat.gaussians import PARAM_NAMES, held_out_gaussians, intrinsics_of, render_frame, to_device
from nerfkit.models.splat.pose_fit import fit_pose
from nerfkit.rays.cameras import Camera


def pinhole_of(camera) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of a view's camera; a DataError (one line for the user) for a lens-distorted one."""
    try:
        return intrinsics_of(camera)
    except ValueError as e:
        raise DataError(str(e)) from None


class SplatRenderer:
    """Full-image rendering of a splat run's active Gaussians (the tile rasteriser; no chunks)."""

    def __init__(self, model):
        self.model = model  # the run's SplatModel (method.py): its background, SH degree and backend
        self._held_out: tuple | None = None  # (the arrays they came from, numpy Gaussians, the same on the device)

    def gaussians(self, params, aux) -> tuple[dict, dict]:
        """(numpy, device) held_out_gaussians of (params, aux), the active Gaussians with the photos' mean colour
        transform folded in; kept while the same arrays come back, so a viewer's or an orbit's frames of one
        model do not select, transform and copy them again each frame (about 10 ms at 50k Gaussians)."""
        source = (aux["active"], *(params[k] for k in (*PARAM_NAMES, "cam_color") if k in params))
        kept = self._held_out
        if kept is None or len(kept[0]) != len(source) or any(a is not b for a, b in zip(kept[0], source)):
            p = held_out_gaussians(params, aux)  # a colour transform learned per photo: their mean
            kept = self._held_out = (source, p, to_device(p))
        return kept[1], kept[2]

    def render_camera(self, params, aux, c2w: np.ndarray, camera, median: bool = False) -> dict:
        """rgb [H, W, 3], depth (sum_k w_k z_k), opacity and depth_normalized (depth / opacity) [H, W]; median: also
        depth_median, each pixel's depth on the Gaussian where its ray turns half opaque (depth.py)."""
        p, on_device = self.gaussians(params, aux)
        intr, g = pinhole_of(camera), self.model.cfg.splat
        r = render_frame(on_device, c2w, camera, self.model.background, g.sh_degree, g.backend,
                         dilation=g.screen_dilation)
        opacity = r["alpha"]
        out = {"rgb": r["rgb"], "depth": r["depth"], "opacity": opacity,
               "depth_normalized": r["depth"] / np.maximum(opacity, 1e-6)}
        if median:
            out["depth_median"] = median_depth(p, c2w, intr, camera.width, camera.height, opacity,
                                               dilation=g.screen_dilation)
        return out

    def fit_pose(self, params, aux, c2w: np.ndarray, camera, image: np.ndarray, iterations: int,
                 fit_colour: bool = False) -> tuple[np.ndarray, dict]:
        """(c2w fitted to the photo image [H, W, 3] against the frozen Gaussians, how far it moved): pose_fit.py
        (`nerfkit eval --fit-poses`; the model's supports.fit_poses); fit_colour: the photo's colour fitted alongside
        (`--fit-colour`)."""
        _, on_device = self.gaussians(params, aux)
        intr, g = pinhole_of(camera), self.model.cfg.splat
        return fit_pose(on_device, c2w, intr, camera.width, camera.height, image, self.model.background,
                        g.sh_degree, iterations, g.backend, g.screen_dilation, fit_color=fit_colour)

    def render_image(self, params, aux, c2w, height: int, width: int, focal: float) -> dict:
        return self.render_camera(params, aux, c2w, Camera.pinhole(width, height, focal))

    def render_cameras(self, params, aux, poses, cameras, median: bool = False) -> list[dict]:
        """render_camera of each (c2w, camera) pair (the rasteriser takes one view at a time)."""
        return [self.render_camera(params, aux, c2w, cam, median) for c2w, cam in zip(poses, cameras)]
