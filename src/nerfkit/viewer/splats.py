"""Gaussian splats drawn by the browser: a splat run's Gaussians handed to viser's own splat renderer.

viser (its WebGL sorter and shader, in the page) draws each Gaussian from its centre mu [3], its 3D
covariance Sigma = R S S^T R^T [3, 3] (R from the unit quaternion, S = diag(exp(log_scales))), one
colour and an opacity sigmoid(logit). nerfkit's Gaussians carry view-dependent colour (spherical
harmonics up to degree 3); the browser gets the degree-0 colour

    c = SH_C0 f_dc + 1/2          (clipped to [0, 1]: the colour seen from every side),

so it draws the scene at the browser's own frame rate, without the view-dependent shine that
nerfkit's rasteriser adds (the viewer's "Drawn by: nerfkit" shows that one, rendered on the server).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.gaussians import held_out_gaussians
from nerfkit.models.splat.project import SH_C0, covariance_3d


def browser_splats(params: dict, aux: dict) -> dict:
    """viser's arrays of a splat run's active Gaussians (normalised frame): centers [N, 3], covariances
    [N, 3, 3], rgbs [N, 3] and opacities [N, 1], float32."""
    p = held_out_gaussians(params, aux)
    cov = np.asarray(covariance_3d(jnp.asarray(p["log_scales"]), jnp.asarray(p["quats"])))
    rgb = np.clip(SH_C0 * p["sh_dc"].reshape(len(p["means"]), -1)[:, :3] + 0.5, 0.0, 1.0)
    opacity = 1.0 / (1.0 + np.exp(-p["opacity"].reshape(-1, 1)))
    return {"centers": p["means"].astype(np.float32), "covariances": cov.astype(np.float32),
            "rgbs": rgb.astype(np.float32), "opacities": opacity.astype(np.float32)}


class SplatLayer:
    """The Gaussians of a viser scene, replaced when new parameters arrive (at most every `every`
    seconds after the first: a frame of 50k Gaussians is ~3 MB for the page to take in)."""

    NAME = "/splats"

    def __init__(self, scene, every: float = 5.0):
        self.scene, self.every = scene, every
        self.handle = None
        self.version = -1  # the parameters' version on screen
        self.sent_at = -np.inf
        self.count = 0

    def due(self, version: int, now: float) -> bool:
        """New parameters that the throttle lets through (the first ones at once)."""
        return version != self.version and (self.handle is None or now - self.sent_at >= self.every)

    def show(self, params, aux, version: int, now: float, visible: bool) -> None:
        """Draw the Gaussians of `params` (replacing the last ones)."""
        arrays = browser_splats(params, aux)
        self.handle = self.scene.add_gaussian_splats(self.NAME, visible=visible, **arrays)
        self.version, self.sent_at, self.count = version, now, len(arrays["centers"])

    def set_visible(self, visible: bool) -> None:
        if self.handle is not None:
            self.handle.visible = visible
