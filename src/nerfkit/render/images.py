"""The image renderer of a model: make_renderer picks the one each model needs (its own for a method that
renders images, as Gaussian splats do; wavefront.py for occupancy-marched fields; chunked.py otherwise), and
check_chunk the --chunk flag the verbs pass it."""

from __future__ import annotations

from nerfkit.core.errors import ConfigError
from nerfkit.render.chunked import Renderer
from nerfkit.render.wavefront import WavefrontRenderer


def check_chunk(chunk: int | None) -> None:
    """ConfigError unless a --chunk value is None (the run's own) or at least 1."""
    if chunk is not None and chunk < 1:
        raise ConfigError(f"--chunk must be >= 1 (got {chunk})")


def check_every(every: int | None) -> None:
    """ConfigError unless an --every value is None (the default spacing) or at least 1."""
    if every is not None and every < 1:
        raise ConfigError(f"--every must be >= 1 (got {every})")


def make_renderer(model, chunk: int = 4096) -> Renderer:
    """The wavefront renderer for models that march an occupancy grid, with 2 * chunk ray slots (a slot is
    small: its window of candidates and up to CAP samples; measured on lego, 2 cores: 800x800 in 3.26 s
    with 8192 slots, 3.89 s with 4096, 3.87 s with 16384), the chunked one otherwise."""
    if model.supports.renders_images:  # a method with its own image renderer (Gaussian splats)
        return model.renderer(chunk)
    return WavefrontRenderer(model, 2 * chunk) if model.supports.marching else Renderer(model, chunk)
