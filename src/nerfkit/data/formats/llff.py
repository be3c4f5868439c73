"""The LLFF capture format: `poses_bounds.npy` + `images/` (+ `masks/`).

poses_bounds.npy is [N, 17] float: per image, in sorted file-name order, a 3x5 matrix
flattened row-major, [R | t | hwf], then the near and far depth bounds. R's columns are
the camera axes in LLFF's order (down, right, backwards) in world coordinates, t the
camera centre, and hwf = (H, W, focal) of the ORIGINAL photos, so the focal length of an
image stored at width w is focal * w / W. In the OpenGL convention (right, up, backwards)
the camera-to-world rotation is [R_1, -R_0, R_2].

Masks (optional, `masks/`): one per image, named like it with any extension, with or
without a `_mask` suffix (IMG_1.JPG -> masks/IMG_1.png or masks/IMG_1_mask.JPG).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.data.capture import Capture, Frame, holdout_splits
from nerfkit.data.images import image_size
from nerfkit.rays.cameras import Camera

IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")


def list_images(folder: Path) -> list[Path]:
    """Image files of a folder (by extension, any case), sorted by name."""
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXTS and p.is_file())


def find_mask(mask_dir: Path, image: Path) -> Path | None:
    """The mask of `image` in mask_dir: same stem (or stem + "_mask", or COLMAP's NAME.png), any extension."""
    if not mask_dir.is_dir():
        return None
    for stem in (image.stem, image.stem + "_mask", image.name):
        for p in sorted(mask_dir.glob(glob_escape(stem) + ".*")):
            if p.suffix.lower() in IMAGE_EXTS and p.stem == stem:
                return p
    return None


def glob_escape(s: str) -> str:
    return "".join(f"[{c}]" if c in "*?[" else c for c in s)


def attach_masks(root: Path, frames: list[Frame], masks: bool) -> None:
    """Give each frame its mask from root/masks (when that folder exists); DataError for a missing one."""
    mask_dir = root / "masks"
    if not masks or not mask_dir.is_dir():
        return
    for f in frames:
        f.mask = find_mask(mask_dir, f.image)
        if f.mask is None:
            raise DataError(f"{mask_dir}: no mask for {f.image.name} (looked for {f.image.stem}.*, "
                            f"{f.image.stem}_mask.*); add it, or pass --no-masks to train without masks")


def llff_to_opengl(pose_3x4: np.ndarray) -> np.ndarray:
    """A 4x4 OpenGL camera-to-world from LLFF's [down, right, backwards | t]."""
    r, t = pose_3x4[:, :3], pose_3x4[:, 3]
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = r[:, 1], -r[:, 0], r[:, 2], t
    return c2w


def read_llff(root: Path, holdout_every: int = 8, masks: bool = True) -> Capture:
    path = root / "poses_bounds.npy"
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as e:
        raise DataError(f"{path}: not a readable .npy array ({type(e).__name__}); re-export it") from None
    images = list_images(root / "images")
    if not images:
        raise DataError(f"{root / 'images'}: no images found; LLFF captures keep their photos in images/")
    if arr.ndim != 2 or arr.shape[1] != 17 or not np.issubdtype(arr.dtype, np.number):
        raise DataError(f"{path}: expected an [N, 17] array (3x5 pose + near, far per image), got shape {arr.shape}")
    if arr.shape[0] != len(images):
        raise DataError(f"{path}: {arr.shape[0]} rows but {len(images)} images in {root / 'images'}; "
                        f"each sorted image needs exactly one row")
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{path}: has non-finite values")
    frames = []
    for k, (row, img) in enumerate(zip(arr.astype(np.float64), images)):
        where = f"{path} row {k} ({img.name})"
        m = row[:15].reshape(3, 5)
        r = m[:, :3]
        if not np.allclose(r.T @ r, np.eye(3), atol=1e-3) or abs(abs(np.linalg.det(r)) - 1) > 1e-3:
            raise DataError(f"{where}: the 3x3 pose part is not a rotation")
        h0, w0, f0 = m[:, 4]
        if min(h0, w0, f0) <= 0:
            raise DataError(f"{where}: H, W, focal must be positive (got {h0:g}, {w0:g}, {f0:g})")
        w, h = image_size(img)
        if abs(w / w0 - h / h0) > 1e-3 * (w / w0):
            raise DataError(f"{where}: the image is {w}x{h} but hwf describes {w0:g}x{h0:g} (another aspect ratio)")
        f = f0 * w / w0
        c2w = llff_to_opengl(m[:, :4])
        if np.linalg.det(c2w[:3, :3]) < 0:
            raise DataError(f"{where}: the pose is mirrored (determinant -1); re-export it")
        frames.append(Frame(img, c2w, Camera.pinhole(w, h, f), None, where))
    attach_masks(root, frames, masks)
    return Capture(root, "llff", holdout_splits(frames, holdout_every), source={"all": str(path)})


def write_llff(root: Path, c2ws: np.ndarray, cameras: list[Camera], bounds: np.ndarray) -> Path:
    """poses_bounds.npy for OpenGL poses [N, 4, 4] of the sorted images/ (pinhole, centred cameras), bounds [N, 2]."""
    rows = []
    for c2w, cam, b in zip(c2ws, cameras, bounds):
        m = np.zeros((3, 5))
        m[:, 0], m[:, 1], m[:, 2], m[:, 3] = -c2w[:3, 1], c2w[:3, 0], c2w[:3, 2], c2w[:3, 3]
        m[:, 4] = cam.height, cam.width, cam.fx
        rows.append(np.concatenate([m.ravel(), b]))
    path = Path(root) / "poses_bounds.npy"
    np.save(path, np.array(rows), allow_pickle=False)
    return path


# -- the format (data/formats/registry.py) ----------------------------------------------------------
NAME = "llff"
LOOKS_FOR = "poses_bounds.npy"


def detect(root: Path) -> bool:
    return (Path(root) / "poses_bounds.npy").exists()


def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
    return read_llff(root, holdout_every, masks)
