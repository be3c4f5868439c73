"""One entry point for every capture format: detect it, select frames, read images and
masks, shrink them, and normalise the poses.

Formats (`--format`, or detected from what the folder holds): data/formats/registry.py.

Masks (white = object) turn into alpha: pixels outside become the background colour, as a
Blender scene's alpha does. Images larger than MAX_SIDE on their long side are shrunk by
the smallest power of two that fits (nerfstudio's rule) unless --downscale says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import DataError
from nerfkit.data.capture import Capture, SceneData, no_data_folder
from nerfkit.data.formats import registry
from nerfkit.data.images import (
    area_downscale,
    check_one_size,
    composite,
    read_masked,
    resolve_downscale,
)
from nerfkit.data.normalize import apply_transform, normalizing_transform
from nerfkit.data.undistort import pinhole_cameras, undistort_image

MAX_SIDE = 1600


def detect_format(root: Path) -> str:
    """The `--format` name of a capture folder (formats/registry.py), or a DataError listing what is looked for."""
    return registry.detect_format(root).NAME


def read_capture(root: str | Path, spec: str, format: str = "auto", masks: bool = True,
                 holdout_every: int = 8) -> Capture:
    """The capture in `root` (frames by split; only the Blender JSONs that `spec` names are read)."""
    root = Path(root)
    fmt = registry.detect_format(root) if format == "auto" else registry.format_named(format, root)
    if not root.is_dir():
        raise no_data_folder(root)
    cap = fmt.read(root, spec, holdout_every, masks)
    if not masks:  # the formats leave masks out when told to: whether there were any to drop is a second read
        try:
            cap.masks_dropped = fmt.read(root, spec, holdout_every, True).has_masks
        except DataError:  # masks, but not one for every photo: --no-masks is the way to train without them
            cap.masks_dropped = True
        for f in cap.all_frames:
            f.mask = None
    return cap


@dataclass
class CaptureFrame:
    """Where the normalised poses and loaded-size cameras of a selection come from."""

    poses: np.ndarray
    cameras: list
    names: list[str]
    transform: np.ndarray
    scale: float
    factor: int


def scene_cameras(cap: Capture, spec: str, downscale: int | None = None, target_width: int | None = None,
                  undistort: bool = False) -> CaptureFrame:
    """Poses (normalised) and cameras (at the loaded size) of the frames `spec` selects, without reading pixels;
    with `undistort`, the pinhole cameras the photos are resampled to (undistort.pinhole_cameras)."""
    frames = cap.frames(spec)
    first = frames[0].camera
    if not cap.levels:  # multiscale data: every level keeps its own size (data/formats/multiscale.py)
        check_one_size([(f.image, (f.camera.width, f.camera.height)) for f in frames])
    exact = cap.format == "blender"
    factor = resolve_downscale(first.width, first.height, downscale, target_width, str(frames[0].image), exact=exact,
                               max_side=None if exact else MAX_SIDE)
    if cap.normalize:
        m, s = normalizing_transform(np.stack([f.c2w for f in cap.all_frames]))
    else:
        m, s = np.eye(4), 1.0
    poses = apply_transform(m, s, np.stack([f.c2w for f in frames])).astype(np.float32)
    cams = [f.camera.scaled(1.0 / factor, f.camera.width // factor, f.camera.height // factor) for f in frames]
    names = [_rel(f.image, cap.root) for f in frames]
    if undistort:
        cams = pinhole_cameras(cams)
    return CaptureFrame(poses, cams, names, m, s, factor)


def _rel(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def load_scene(root: str | Path, spec: str, *, format: str = "auto", downscale: int | None = None,
               target_width: int | None = None, background: str = "white", masks: bool = True,
               holdout_every: int = 8, progress: bool = False, undistort: bool = False) -> SceneData:
    """Load the frames a split spec selects (e.g. "train,val[0:50]" or "test") as SceneData."""
    cap = read_capture(root, spec, format, masks, holdout_every)
    return load_frames(cap, spec, downscale=downscale, target_width=target_width, background=background,
                       progress=progress, undistort=undistort)


def load_frames(cap: Capture, spec: str, *, downscale: int | None = None, target_width: int | None = None,
                background: str = "white", progress: bool = False, undistort: bool = False) -> SceneData:
    """Read, mask, composite and shrink the images of `spec` (see load_scene); with `undistort`, resample
    photos of lens-distorted cameras as pinhole cameras see them (data/undistort.py), after shrinking."""
    sel = scene_cameras(cap, spec, downscale, target_width, undistort)
    bg = np.ones(3) if background == "white" else np.zeros(3)
    frames = cap.frames(spec)
    images, alphas = [], []
    use_alpha = cap.alpha or any(f.mask is not None for f in frames)
    for f, cam in tqdm(list(zip(frames, sel.cameras)), desc="load images", unit="img",
                       disable=not progress or len(frames) < 20, leave=False):
        rgb, a = read_masked(f.image, f.mask, (f.camera.width, f.camera.height))
        shrunk = f.camera.scaled(1.0 / sel.factor, f.camera.width // sel.factor, f.camera.height // sel.factor)
        image, a = area_downscale(composite(rgb, a, bg), sel.factor), area_downscale(a, sel.factor)
        if shrunk != cam:  # undistorted: the pinhole camera sees another picture
            image, a = undistort_image(image, shrunk, cam), undistort_image(a, shrunk, cam)
        images.append(image)
        if use_alpha:
            alphas.append(np.round(a * 255).astype(np.uint8))
    sizes = np.array([(c.height, c.width) for c in sel.cameras], np.int32)
    mixed = len({tuple(x) for x in sizes}) > 1
    return SceneData(pad_stack(images).astype(np.float32), sel.poses, sel.cameras, sel.names, sel.transform,
                     sel.scale, cap.format, any(f.mask is not None for f in frames),
                     pad_stack(alphas) if use_alpha else None, sizes if mixed else None)


def pad_stack(images: list[np.ndarray]) -> np.ndarray:
    """Images of different sizes [H_k, W_k, ...] stacked into [N, max H, max W, ...], zero-padded at the
    bottom and right (SceneData.sizes says how much of each is image)."""
    h = max(im.shape[0] for im in images)
    w = max(im.shape[1] for im in images)
    out = np.zeros((len(images), h, w, *images[0].shape[2:]), images[0].dtype)
    for k, im in enumerate(images):
        out[k, :im.shape[0], :im.shape[1]] = im
    return out
