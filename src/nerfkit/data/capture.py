"""What every capture format is read into, and the split specs that select its frames.

A format reader (blender, nerfstudio, llff, colmap) turns a folder into a `Capture`:
named splits of `Frame`s, each an image file, its camera-to-world pose (OpenGL
convention, in the capture's own coordinates), its intrinsics (`cameras.Camera`, at the
image's size on disk) and an optional object mask. `loader.load_scene` then selects the
frames of a split spec, reads and shrinks the images, applies masks and normalises the
poses into a `SceneData`.

Split specs: a comma-separated list of `split` or `split[a:b]` (a Python slice of that
split's frames), e.g. "train,val[0:50]". Formats without splits of their own hold out
every N-th frame (sorted by file name, index % N == 0) as `test`, the rest is `train`,
and `all` is every frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.rays.cameras import Camera

_SPEC_ITEM = re.compile(r"^\s*([A-Za-z0-9_\-]+)\s*(?:\[\s*(-?\d+)?\s*:\s*(-?\d+)?\s*\])?\s*$")


@dataclass
class SplitItem:
    split: str
    start: int | None = None
    stop: int | None = None

    def __str__(self) -> str:
        if self.start is None and self.stop is None:
            return self.split
        a = "" if self.start is None else self.start
        b = "" if self.stop is None else self.stop
        return f"{self.split}[{a}:{b}]"


def no_data_folder(root: Path) -> DataError:
    """The one-line error for a data folder `root` that is missing or is a file."""
    return DataError(f"{root}: " + ("is a file, not a data folder" if Path(root).exists() else
                                    "data folder does not exist"))


def parse_split_spec(spec: str) -> list[SplitItem]:
    """Parse "train,val[0:50]" into split items (Python slice semantics on frame lists)."""
    if not isinstance(spec, str) or not spec.strip():
        raise DataError(f"empty split spec {spec!r}; use e.g. 'train' or 'train,val[0:50]'")
    items = []
    for part in spec.split(","):
        m = _SPEC_ITEM.match(part)
        if not m:
            raise DataError(f"bad split spec {part.strip()!r} in {spec!r}; use 'split' or 'split[a:b]', e.g. 'val[0:50]'")
        name, a, b = m.groups()
        items.append(SplitItem(name, int(a) if a else None, int(b) if b else None))
    return items


def select(where: str, item: SplitItem, n: int) -> list[int]:
    """Indices of `item`'s frames in a split of n frames; DataError if out of range or empty."""
    for bound in (item.start, item.stop):
        if bound is not None and not (-n <= bound <= n):
            raise DataError(f"{where}: index {bound} in '{item}' is out of range; split {item.split!r} has {n} frames")
    chosen = list(range(n))[slice(item.start, item.stop)]
    if not chosen:
        raise DataError(f"{where}: '{item}' selects no frames (split has {n}); fix the split spec")
    return chosen


@dataclass
class Frame:
    """One photo: its file, camera-to-world pose [4, 4] (OpenGL, capture coordinates),
    intrinsics at the size of the file on disk, optional mask, and where it was described
    (for error messages)."""

    image: Path
    c2w: np.ndarray
    camera: Camera
    mask: Path | None = None
    where: str = ""


@dataclass
class Capture:
    """Frames of a capture folder, by split.

    format: "blender" | "nerfstudio" | "llff" | "colmap".
    splits: split name -> frames; `where(split)` names the file a split comes from.
    normalize: whether poses must be normalised (the Blender scenes already are).
    alpha: whether images carry their own alpha (the Blender scenes).
    points: optional [P, 3] sparse points (capture coordinates) from SfM; point_colors [P, 3] in [0, 1]
            (grey where the file has none); points_file: the file or model they were read from.
    source: split name -> the file it comes from (for error messages).
    """

    root: Path
    format: str
    splits: dict[str, list[Frame]]
    normalize: bool = True
    alpha: bool = False
    points: np.ndarray | None = None
    point_colors: np.ndarray | None = None
    points_file: str | None = None
    source: dict[str, str] = field(default_factory=dict)
    hint: str | None = None
    """"bounded" when the files say the scene fits a box (instant-ngp's aabb_scale 1)."""
    levels: dict[str, int] = field(default_factory=dict)
    """Splits holding L > 1 levels of the same views, level-major (multiscale.py): a slice selects views."""
    own_splits: bool = False
    """The splits come from the files (Blender's transforms_{split}.json, nerfstudio's *_filenames), not
    from holding out every N-th frame."""
    masks_dropped: bool = False
    """The capture has object masks that --no-masks told the reader to ignore."""

    def where(self, split: str) -> str:
        return self.source.get(split, str(self.root))

    @property
    def all_frames(self) -> list[Frame]:
        if "all" in self.splits:
            return self.splits["all"]
        seen, out = set(), []
        for frames in self.splits.values():
            for f in frames:
                if id(f) not in seen:
                    seen.add(id(f))
                    out.append(f)
        return out

    @property
    def has_masks(self) -> bool:
        return any(f.mask is not None for f in self.all_frames)

    @property
    def photos(self) -> bool:
        """Photos without masks, whose poses and exposure vary from photo to photo: neither a Blender scene nor
        a masked capture (what the per-photo corrections' auto settings turn on for)."""
        return self.format != "blender" and not self.has_masks

    def frames(self, spec: str) -> list[Frame]:
        """The frames a split spec selects, in order."""
        out = []
        for item in parse_split_spec(spec):
            if item.split not in self.splits:
                have = ", ".join(sorted(self.splits))
                raise DataError(f"{self.root}: no split {item.split!r} in this {self.format} capture (it has: {have}); "
                                f"fix the split spec")
            frames = self.splits[item.split]
            n_levels = self.levels.get(item.split, 1)
            n = len(frames) // n_levels
            out += [frames[lvl * n + k] for lvl in range(n_levels) for k in select(self.where(item.split), item, n)]
        return out


def holdout_splits(frames: list[Frame], every: int) -> dict[str, list[Frame]]:
    """train / test / all of frames sorted by file name: test = index % every == 0."""
    if every < 1:
        raise DataError(f"--holdout-every must be >= 1 (got {every})")
    frames = sorted(frames, key=lambda f: str(f.image))
    test = [f for k, f in enumerate(frames) if k % every == 0]
    train = [f for k, f in enumerate(frames) if k % every != 0] if len(frames) > 1 else list(frames)
    return {"train": train, "test": test, "all": frames}


@dataclass
class SceneData:
    """Images and cameras of one or more splits, at one resolution, in normalised coordinates.

    images:  [N, H, W, 3] float32 in [0, 1], composited on the background.
    poses:   [N, 4, 4] float32 camera-to-world (OpenGL convention).
    cameras: N intrinsics (`Camera`, at the loaded size); all frames share one size.
    transform: [4, 4] similarity taking capture coordinates to these (identity for
      Blender scenes); `scale` its scale factor (depths divide by it to come back).
    """

    images: np.ndarray
    poses: np.ndarray
    cameras: list[Camera]
    names: list[str] = field(default_factory=list)
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    scale: float = 1.0
    format: str = "blender"
    has_masks: bool = False
    alphas: np.ndarray | None = None
    """[N, H, W] uint8 coverage (a PNG's alpha or the object mask), None where images are opaque."""
    sizes: np.ndarray | None = None
    """[N, 2] (height, width) of each image when they differ (multiscale data: images and alphas are
    then zero-padded to the largest, and image(k) crops); None when all share the cameras' size."""

    def image(self, k: int) -> np.ndarray:
        """Image k [H_k, W_k, 3] (without padding)."""
        c = self.cameras[k]
        return self.images[k, :c.height, :c.width]

    @property
    def lossmult(self) -> np.ndarray:
        """[N] area of each image's pixels in pixels of the largest image, (W_max / W_k)^2: mip-NeRF's
        loss weights, which make every scale count alike when rays are drawn per pixel."""
        w = np.array([c.width for c in self.cameras], np.float32)
        return (w.max() / w) ** 2

    def __len__(self) -> int:
        return len(self.images)

    @property
    def height(self) -> int:
        return self.cameras[0].height

    @property
    def width(self) -> int:
        return self.cameras[0].width

    @property
    def focal(self) -> float:
        """Horizontal focal length in pixels of the first frame."""
        return self.cameras[0].fx


def scene_type(setting: str, cap: Capture) -> tuple[str, str]:
    """(bounded | unbounded, why) of a capture under --scene-type `setting` (auto: from the data: Blender
    scenes, masked captures and aabb_scale 1 are bounded; photos without masks are not)."""
    if setting != "auto":
        return setting, "--scene-type"
    if cap.format == "blender":
        return "bounded", "Blender scene"
    if cap.has_masks:
        return "bounded", "masked capture"
    if cap.hint == "bounded":
        return "bounded", "aabb_scale 1"
    return "unbounded", "photos without masks"
