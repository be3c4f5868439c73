"""Rendering full images with a trained model, in fixed-size chunks of rays.

Memory is bounded by the chunk size, not the image size: one compiled function renders
`chunk` rays at a time (the last chunk is padded), and only the per-pixel outputs
(rgb, depth, opacity) of the whole image are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.cameras import Camera, camera_rays

OUTPUT_KEYS = ("rgb", "depth", "depth_normalized", "opacity")


@dataclass
class Renderer:
    """Chunked full-image rendering for one model (compiles once per chunk size)."""

    model: object
    chunk: int = 4096

    def __post_init__(self):
        model = self.model

        def render_chunk(params, aux, o, d):
            out = model.render_rays(params, aux, o, d, jax.random.PRNGKey(0), train=False)
            res = {k: out[k] for k in OUTPUT_KEYS}
            res["complete"] = out.get("complete", jnp.ones(o.shape[0], bool))
            return res

        self._render_chunk = jax.jit(render_chunk)

    def render_rays(self, params, aux, origins: np.ndarray, directions: np.ndarray) -> dict:
        """Render rays [N, 3] chunk by chunk; returns numpy arrays rgb [N, 3], depth [N], ...

        Models with a per-chunk sample budget mark rays that did not fit as incomplete;
        those rays go to the front of the next chunk (the first ray of a chunk always fits).
        """
        n = origins.shape[0]
        outs = {k: np.zeros((n, 3) if k == "rgb" else (n,), np.float32) for k in OUTPUT_KEYS}
        pending = np.arange(n)
        while pending.size:
            idx = pending[:self.chunk]
            m = idx.size
            if m < self.chunk:  # pad to the compiled size with copies of the last ray
                idx = np.concatenate([idx, np.full(self.chunk - m, idx[-1])])
            res = self._render_chunk(params, aux, jnp.asarray(origins[idx]), jnp.asarray(directions[idx]))
            done = np.asarray(res["complete"])[:m]
            if not done[0]:
                raise RuntimeError("a single ray needs more samples than the render budget")
            for k in OUTPUT_KEYS:
                outs[k][idx[:m][done]] = np.asarray(res[k])[:m][done]
            pending = np.concatenate([pending[:m][~done], pending[m:]])
        return outs

    def render_image(self, params, aux, c2w: np.ndarray, height: int, width: int, focal: float) -> dict:
        """rgb [H, W, 3], depth / depth_normalized / opacity [H, W] of an ideal pinhole camera at c2w."""
        return self.render_camera(params, aux, c2w, Camera.pinhole(width, height, focal))

    def render_camera(self, params, aux, c2w: np.ndarray, camera: Camera) -> dict:
        """rgb [H, W, 3], depth / depth_normalized / opacity [H, W] of `camera` (lens model included) at c2w.
        Appearance embeddings, where the model has them, are the mean over training images."""
        o, d = camera_rays(c2w, camera)
        out = self.render_rays(params, aux, o.reshape(-1, 3), d.reshape(-1, 3))
        return {k: v.reshape(camera.height, camera.width, *v.shape[1:]) for k, v in out.items()}
