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

from nerfkit.cameras import image_rays

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
            return {k: out[k] for k in OUTPUT_KEYS}

        self._render_chunk = jax.jit(render_chunk)

    def render_rays(self, params, aux, origins: np.ndarray, directions: np.ndarray) -> dict:
        """Render rays [N, 3] chunk by chunk; returns numpy arrays rgb [N, 3], depth [N], ..."""
        n = origins.shape[0]
        outs = {k: [] for k in OUTPUT_KEYS}
        for start in range(0, n, self.chunk):
            o = origins[start:start + self.chunk]
            d = directions[start:start + self.chunk]
            m = o.shape[0]
            if m < self.chunk:  # pad to the compiled size
                o = np.concatenate([o, np.repeat(o[-1:], self.chunk - m, 0)])
                d = np.concatenate([d, np.repeat(d[-1:], self.chunk - m, 0)])
            res = self._render_chunk(params, aux, jnp.asarray(o), jnp.asarray(d))
            for k in OUTPUT_KEYS:
                outs[k].append(np.asarray(res[k])[:m])
        return {k: np.concatenate(v) for k, v in outs.items()}

    def render_image(self, params, aux, c2w: np.ndarray, height: int, width: int, focal: float) -> dict:
        """rgb [H, W, 3], depth / depth_normalized / opacity [H, W] of the camera c2w."""
        o, d = image_rays(c2w, height, width, focal)
        out = self.render_rays(params, aux, o.reshape(-1, 3), d.reshape(-1, 3))
        return {k: v.reshape(height, width, *v.shape[1:]) for k, v in out.items()}
