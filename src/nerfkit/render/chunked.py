"""Rendering full images with a trained model, in fixed-size chunks of rays (the renderer of every ray model
that does not march an occupancy grid; those render with wavefront.py, splats with their own).

Memory is bounded by the chunk size, not the image size: one compiled function renders
`chunk` rays at a time (the last chunk is padded), and only the per-pixel outputs
(rgb, depth, opacity) of the whole image are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.rays.cameras import Camera, camera_rays
from nerfkit.rays.frustum import pixel_base_radius

OUTPUT_KEYS = ("rgb", "depth", "depth_normalized", "opacity")


@dataclass
class Renderer:
    """Chunked full-image rendering for one model (compiles once per chunk size)."""

    model: object
    chunk: int = 4096

    def __post_init__(self):
        model = self.model

        def render_chunk(params, aux, o, d, radii, median):
            out = model.render_rays(params, aux, o, d, jax.random.PRNGKey(0), train=False, radii=radii)
            res = {k: out[k] for k in OUTPUT_KEYS + (("depth_median",) if median else ())}
            res["complete"] = out.get("complete", jnp.ones(o.shape[0], bool))
            return res

        self._render_chunk = jax.jit(render_chunk, static_argnums=5)

    def render_rays(self, params, aux, origins: np.ndarray, directions: np.ndarray,
                    radii: np.ndarray | None = None, median: bool = False) -> dict:
        """Render rays [N, 3] (cones of radii [N] per unit z-depth for the anti-aliased models; None: thin
        rays) chunk by chunk; returns numpy arrays rgb [N, 3], depth, depth_normalized, opacity [N], and
        with `median` depth_median [N] (render/volume.py; the volume-rendered models give it).

        Models with a per-chunk sample budget mark rays that did not fit as incomplete;
        those rays go to the front of the next chunk (the first ray of a chunk always fits).
        """
        n = origins.shape[0]
        radii = np.zeros(n, np.float32) if radii is None else np.broadcast_to(np.asarray(radii, np.float32), (n,))
        outs = {k: np.zeros((n, 3) if k == "rgb" else (n,), np.float32)
                for k in OUTPUT_KEYS + (("depth_median",) if median else ())}
        pending = np.arange(n)
        while pending.size:
            idx = pending[:self.chunk]
            m = idx.size
            if m < self.chunk:  # pad to the compiled size with copies of the last ray
                idx = np.concatenate([idx, np.full(self.chunk - m, idx[-1])])
            res = self._render_chunk(params, aux, jnp.asarray(origins[idx]), jnp.asarray(directions[idx]),
                                     jnp.asarray(radii[idx]), median)
            done = np.asarray(res["complete"])[:m]
            if not done[0]:
                raise RuntimeError("a single ray needs more samples than the render budget")
            for k in outs:
                outs[k][idx[:m][done]] = np.asarray(res[k])[:m][done]
            pending = np.concatenate([pending[:m][~done], pending[m:]])
        return outs

    def render_image(self, params, aux, c2w: np.ndarray, height: int, width: int, focal: float) -> dict:
        """rgb [H, W, 3], depth / depth_normalized / opacity [H, W] of an ideal pinhole camera at c2w."""
        return self.render_camera(params, aux, c2w, Camera.pinhole(width, height, focal))

    def render_camera(self, params, aux, c2w: np.ndarray, camera: Camera, median: bool = False) -> dict:
        """rgb [H, W, 3], depth / depth_normalized / opacity [H, W] (and with `median` depth_median) of
        `camera` (lens model included) at c2w. Appearance embeddings, where the model has them, are the
        mean over training images; the anti-aliased models see cones of the camera's pixel size
        (frustum.pixel_base_radius)."""
        return self.render_cameras(params, aux, [c2w], [camera], median)[0]

    def render_cameras(self, params, aux, poses, cameras: list[Camera], median: bool = False) -> list[dict]:
        """render_camera of each (c2w, camera) pair, the rays of all of them rendered in one render_rays call:
        views smaller than the renderer's chunk (or its wavefront's slots) keep it full instead of each
        leaving part of it empty."""
        rays = [camera_rays(c2w, cam) for c2w, cam in zip(poses, cameras)]
        sizes = [cam.width * cam.height for cam in cameras]
        o = np.concatenate([o.reshape(-1, 3) for o, _ in rays])
        d = np.concatenate([d.reshape(-1, 3) for _, d in rays])
        radii = np.concatenate([np.full(n, float(pixel_base_radius(cam.fx, cam.fy)), np.float32)
                                for n, cam in zip(sizes, cameras)])
        out = self.render_rays(params, aux, o, d, radii, median)
        ends = np.cumsum(sizes)
        return [{k: v[end - n:end].reshape(cam.height, cam.width, *v.shape[1:]) for k, v in out.items()}
                for n, end, cam in zip(sizes, ends, cameras)]
