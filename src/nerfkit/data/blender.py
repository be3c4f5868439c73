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
from PIL import Image

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
    if path.exists() and not path.is_file():
        raise DataError(f"{path}: is not a regular file; split {split!r} needs the transforms JSON there")
    if not path.is_file():
        have = sorted(p.name for p in root.glob("transforms_*.json"))
        hint = f" (found: {', '.join(have)})" if have else " (no transforms_*.json in that folder)"
        raise DataError(f"{path}: missing; split {split!r} needs this file{hint}")
    try:
        meta = json.loads(path.read_text(encoding="utf-8-sig"))  # -sig: tolerate a UTF-8 byte-order mark
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: not valid JSON ({_one_line(e)}); fix or re-export the file") from None
    except RecursionError:
        raise DataError(f"{path}: not valid transforms JSON (nested too deeply); fix or re-export the file") from None
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
    except (TypeError, ValueError, OverflowError):
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


def _is_file(p: Path) -> bool:
    try:
        return p.is_file()
    except (OSError, ValueError):  # e.g. a name too long for the file system
        return False


def _image_path(root: Path, file_path: str, where: str) -> Path:
    if "\x00" in file_path:
        raise DataError(f"{where}: file_path {file_path!r} contains a NUL character; fix the transforms JSON")
    p = root / file_path
    if p.suffix.lower() != ".png":
        with_png = p.with_name(p.name + ".png") if p.name else p
        if _is_file(with_png) or not _is_file(p):
            p = with_png
    if not _is_file(p):
        raise DataError(f"{p}: missing image for {where}; fix its file_path or add the image")
    return p


# Pillow modes read as they are (palette and 1-bit images are expanded), and the 16-bit gray ones.
_COLOR_MODES = ("1", "L", "LA", "P", "PA", "RGB", "RGBA")
_GRAY16_MODES = ("I;16", "I;16B", "I;16L", "I")


def _one_line(e: BaseException, limit: int = 200) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def load_image(path: Path, background: np.ndarray, expect_size: tuple[int, int] | None = None) -> np.ndarray:
    """Read an image as float32 RGB in [0, 1], compositing alpha on `background`.

    Accepted: 8-bit RGB / RGBA (RGB without alpha is fully opaque), 8- or 16-bit gray
    (with or without alpha), 1-bit and palette images; 16-bit RGB(A) is read at 8 bits.
    Refused with a DataError: other modes (CMYK, float, ...), unreadable or truncated
    files, and (checked from the header, before decoding) a size other than
    `expect_size` = (width, height).
    """
    try:
        with Image.open(path) as im:
            if expect_size is not None and im.size != tuple(expect_size):
                raise DataError(f"{path}: image is {im.size[0]}x{im.size[1]} but earlier frames are "
                                f"{expect_size[0]}x{expect_size[1]}; all images must have one size")
            mode = im.mode
            if mode not in _COLOR_MODES + _GRAY16_MODES:
                raise DataError(f"{path}: unsupported image mode {mode!r}; "
                                f"save it as an 8-bit RGB/RGBA or 8/16-bit grayscale PNG")
            im.load()
            if im.mode in _GRAY16_MODES:
                gray = np.asarray(im).astype(np.float64)
                if gray.size and (gray.min() < 0 or gray.max() > 65535):
                    raise DataError(f"{path}: {mode} pixel values outside 0..65535; save it as an 8- or 16-bit PNG")
                rgb = np.repeat((gray / 65535.0)[..., None], 3, -1)
                a = np.ones(gray.shape, np.float64)
            else:
                arr = np.asarray(im.convert("RGBA"), dtype=np.float64) / 255.0
                rgb, a = arr[..., :3], arr[..., 3]
    except DataError:
        raise
    except Image.DecompressionBombError as e:
        raise DataError(f"{path}: image too large to load ({_one_line(e)}); shrink it") from None
    except MemoryError:
        raise DataError(f"{path}: not enough memory to decode this image; shrink it") from None
    except Exception as e:  # noqa: BLE001 - Pillow raises many unrelated types on corrupt files
        raise DataError(f"{path}: unreadable or truncated image ({type(e).__name__}: {_one_line(e)}); "
                        f"re-export it as PNG") from None
    if rgb.ndim != 3 or rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise DataError(f"{path}: image has no pixels ({rgb.shape}); re-export it as PNG")
    out = rgb * a[..., None] + (1.0 - a[..., None]) * background
    return out.astype(np.float32)


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


def _select(jpath: Path, item: SplitItem, n: int) -> list[int]:
    """Indices of `item`'s frames in a split of n frames; DataError if out of range or empty."""
    for bound in (item.start, item.stop):
        if bound is not None and not (-n <= bound <= n):
            raise DataError(f"{jpath}: index {bound} in '{item}' is out of range; split {item.split!r} has {n} frames")
    chosen = list(range(n))[slice(item.start, item.stop)]
    if not chosen:
        raise DataError(f"{jpath}: '{item}' selects no frames (split has {n}); fix the split spec")
    return chosen


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
    bg = np.array([1.0, 1.0, 1.0]) if background == "white" else np.zeros(3)
    images, poses, names = [], [], []
    size = None
    factor = None
    fov = None
    for where, frame, pose, fov in iter_frames(root, spec):
        path = _image_path(root, frame["file_path"], where)
        img = load_image(path, bg, expect_size=None if size is None else (size[1], size[0]))
        h, w = img.shape[:2]
        if size is None:
            size = (h, w)
            factor = resolve_downscale(w, h, downscale, target_width, str(path))
        images.append(area_downscale(img, factor))
        poses.append(pose)
        names.append(str(path.relative_to(root)))
    h, w = images[0].shape[:2]
    focal = 0.5 * w / math.tan(0.5 * fov)
    return SceneData(np.stack(images), np.stack(poses), float(focal), h, w, names)


def iter_frames(root: Path, spec: str):
    """Yield (where, frame dict, checked pose [4, 4], camera_angle_x) for every frame of a
    split spec, checking the folder, each transforms JSON, index ranges, poses, and that
    all splits share one field of view."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: data folder does not exist")
    fov = None
    for item in parse_split_spec(spec):
        meta = read_transforms(root, item.split)
        jpath = root / f"transforms_{item.split}.json"
        if fov is not None and abs(meta["camera_angle_x"] - fov) > 1e-6:
            raise DataError(f"{jpath}: camera_angle_x {meta['camera_angle_x']} differs from the other splits ({fov})")
        fov = float(meta["camera_angle_x"])
        frames = meta["frames"]
        for k in _select(jpath, item, len(frames)):
            where = f"{jpath} frame {k}"
            yield where, frames[k], check_pose(frames[k]["transform_matrix"], where), fov


def read_split_poses(root: str | Path, spec: str) -> tuple[np.ndarray, float]:
    """Poses [N, 4, 4] and camera_angle_x of a split spec, without reading images."""
    poses, fov = [], None
    for _, _, pose, fov in iter_frames(root, spec):
        poses.append(pose)
    if not poses:
        raise DataError(f"{root}: split spec {spec!r} selects no frames")
    return np.stack(poses), fov
