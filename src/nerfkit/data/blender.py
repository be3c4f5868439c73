"""The NeRF "Blender synthetic" format: `transforms_{split}.json` + RGBA PNGs.

JSON: `camera_angle_x` (horizontal field of view, radians) and `frames`, each with
`file_path` (relative, usually without extension) and `transform_matrix`, the 4x4
camera-to-world matrix in the OpenGL convention (camera looks down -z, +y up).

    focal = 0.5 * W / tan(0.5 * camera_angle_x)

RGBA images are composited on a background colour: rgb = a * rgb + (1 - a) * bg.
Every problem with the data is reported as a `DataError` naming the file, before any
compute is spent.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from nerfkit.errors import DataError

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


@dataclass
class SceneData:
    """Images and cameras of one or more splits, at one resolution.

    images: [N, H, W, 3] float32 in [0, 1], composited on the background.
    poses:  [N, 4, 4] float32 camera-to-world (OpenGL convention).
    """

    images: np.ndarray
    poses: np.ndarray
    focal: float
    height: int
    width: int
    names: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.images)


def read_transforms(root: Path, split: str) -> dict:
    """Read and check `root/transforms_{split}.json`."""
    path = root / f"transforms_{split}.json"
    if not path.is_file():
        have = sorted(p.name for p in root.glob("transforms_*.json"))
        hint = f" (found: {', '.join(have)})" if have else " (no transforms_*.json in that folder)"
        raise DataError(f"{path}: missing; split {split!r} needs this file{hint}")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: not valid JSON ({e})") from None
    except OSError as e:
        raise DataError(f"{path}: unreadable ({e.strerror})") from None
    if not isinstance(meta, dict):
        raise DataError(f"{path}: expected a JSON object with 'camera_angle_x' and 'frames'")
    if "camera_angle_x" not in meta:
        raise DataError(f"{path}: no 'camera_angle_x' (horizontal field of view in radians)")
    fov = meta["camera_angle_x"]
    if isinstance(fov, bool) or not isinstance(fov, (int, float)) or not (0 < fov < math.pi):
        raise DataError(f"{path}: 'camera_angle_x' must be a number in (0, pi), got {fov!r}")
    frames = meta.get("frames")
    if not isinstance(frames, list):
        raise DataError(f"{path}: no 'frames' list")
    for k, fr in enumerate(frames):
        if not isinstance(fr, dict) or not isinstance(fr.get("file_path"), str) or "transform_matrix" not in fr:
            raise DataError(f"{path}: frame {k} needs 'file_path' (string) and 'transform_matrix'")
    return meta


def check_pose(m, where: str) -> np.ndarray:
    """A 4x4 finite rigid camera-to-world matrix, or DataError."""
    try:
        pose = np.asarray(m, dtype=np.float64)
    except (TypeError, ValueError):
        raise DataError(f"{where}: transform_matrix is not a 4x4 matrix of numbers") from None
    if pose.shape == (3, 4):
        pose = np.concatenate([pose, [[0, 0, 0, 1]]], 0)
    if pose.shape != (4, 4):
        raise DataError(f"{where}: transform_matrix must be 4x4, got shape {pose.shape}")
    if not np.all(np.isfinite(pose)):
        raise DataError(f"{where}: transform_matrix has non-finite values")
    r = pose[:3, :3]
    # A camera-to-world rotation: orthonormal columns, det +1 (Blender exports are exact to ~1e-6).
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-3) or abs(np.linalg.det(r) - 1) > 1e-3:
        raise DataError(f"{where}: transform_matrix is not rigid (its 3x3 part is not a rotation)")
    if not np.allclose(pose[3], [0, 0, 0, 1], atol=1e-6):
        raise DataError(f"{where}: transform_matrix last row must be [0, 0, 0, 1]")
    return pose.astype(np.float32)


def _image_path(root: Path, file_path: str, where: str) -> Path:
    p = root / file_path
    if p.suffix.lower() != ".png":
        with_png = p.with_name(p.name + ".png")
        if with_png.is_file() or not p.is_file():
            p = with_png
    if not p.is_file():
        raise DataError(f"{p}: missing image for {where}")
    return p


def load_image(path: Path, background: np.ndarray) -> np.ndarray:
    """Read an image as float32 RGB in [0, 1], compositing alpha on `background`.

    Accepted: 8- or 16-bit gray, gray+alpha, RGB, RGBA (RGB without alpha is taken as
    fully opaque). Anything else (palette images are converted; CMYK etc. refused).
    """
    try:
        with Image.open(path) as im:
            im.load()
            mode = im.mode
            if mode == "P":
                im = im.convert("RGBA")
                mode = "RGBA"
            if mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im, dtype=np.float64)
                peak = 65535.0 if arr.max(initial=0) > 255 or mode.startswith("I;16") else 255.0
                rgba = np.repeat((arr / peak)[..., None], 3, -1)
                a = np.ones(arr.shape, np.float64)
            elif mode in ("L", "LA", "RGB", "RGBA"):
                arr = np.asarray(im.convert("RGBA"), dtype=np.float64) / 255.0
                rgba, a = arr[..., :3], arr[..., 3]
            else:
                raise DataError(f"{path}: unsupported image mode {mode!r}; use RGB or RGBA PNG")
    except DataError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise DataError(f"{path}: unreadable or truncated image ({e})") from None
    rgb = rgba * a[..., None] + (1.0 - a[..., None]) * background
    return rgb.astype(np.float32)


def area_downscale(img: np.ndarray, factor: int) -> np.ndarray:
    """Average non-overlapping factor x factor blocks: [H, W, C] -> [H/f, W/f, C]."""
    if factor == 1:
        return img
    h, w, c = img.shape
    return img.reshape(h // factor, factor, w // factor, factor, c).mean(axis=(1, 3))


def resolve_downscale(width: int, height: int, downscale: int | None, target_width: int | None, where: str) -> int:
    """The integer factor to shrink images by (see DataConfig)."""
    if downscale is None:
        if target_width is None:
            return 1
        if width % target_width:
            raise DataError(f"{where}: image width {width} is not a multiple of --target-width {target_width}; pass --downscale instead")
        downscale = width // target_width
    if downscale < 1 or width % downscale or height % downscale:
        raise DataError(f"{where}: --downscale {downscale} does not divide the image size {width}x{height}")
    return downscale


def load_blender(
    root: str | Path,
    spec: str,
    *,
    downscale: int | None = None,
    target_width: int | None = None,
    background: str = "white",
) -> SceneData:
    """Load the frames named by `spec` (e.g. "train,val[0:50]") from a Blender-format folder."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: data folder does not exist")
    bg = np.array([1.0, 1.0, 1.0]) if background == "white" else np.zeros(3)
    images, poses, names = [], [], []
    fov = None
    size = None
    factor = None
    for item in parse_split_spec(spec):
        meta = read_transforms(root, item.split)
        jpath = root / f"transforms_{item.split}.json"
        if fov is not None and abs(meta["camera_angle_x"] - fov) > 1e-6:
            raise DataError(f"{jpath}: camera_angle_x {meta['camera_angle_x']} differs from the other splits ({fov})")
        fov = float(meta["camera_angle_x"])
        frames = meta["frames"]
        n = len(frames)
        for bound in (item.start, item.stop):
            if bound is not None and not (-n <= bound <= n):
                raise DataError(f"{jpath}: index {bound} in '{item}' is out of range; split {item.split!r} has {n} frames")
        chosen = list(range(n))[slice(item.start, item.stop)]
        if not chosen:
            raise DataError(f"{jpath}: '{item}' selects no frames (split has {n})")
        for k in chosen:
            where = f"{jpath} frame {k}"
            pose = check_pose(frames[k]["transform_matrix"], where)
            path = _image_path(root, frames[k]["file_path"], where)
            img = load_image(path, bg)
            h, w = img.shape[:2]
            if size is None:
                size = (h, w)
                factor = resolve_downscale(w, h, downscale, target_width, str(path))
            elif (h, w) != size:
                raise DataError(f"{path}: image is {w}x{h} but earlier frames are {size[1]}x{size[0]}; all images must have one size")
            images.append(area_downscale(img, factor))
            poses.append(pose)
            names.append(str(path.relative_to(root)))
    h, w = images[0].shape[:2]
    focal = 0.5 * w / math.tan(0.5 * fov)
    return SceneData(np.stack(images), np.stack(poses), float(focal), h, w, names)


def read_split_poses(root: str | Path, spec: str) -> tuple[np.ndarray, float]:
    """Poses [N, 4, 4] and camera_angle_x of a split spec, without reading images."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: data folder does not exist")
    poses, fov = [], None
    for item in parse_split_spec(spec):
        meta = read_transforms(root, item.split)
        fov = float(meta["camera_angle_x"])
        jpath = root / f"transforms_{item.split}.json"
        for k in list(range(len(meta["frames"])))[slice(item.start, item.stop)]:
            poses.append(check_pose(meta["frames"][k]["transform_matrix"], f"{jpath} frame {k}"))
    if not poses:
        raise DataError(f"{root}: split spec {spec!r} selects no frames")
    return np.stack(poses), fov
