"""The NeRF "Blender synthetic" format: `transforms_{split}.json` + RGBA PNGs.

JSON: `camera_angle_x` (horizontal field of view, radians) and `frames`, each with
`file_path` (relative, usually without extension) and `transform_matrix`, the 4x4
camera-to-world matrix in the OpenGL convention (camera looks down -z, +y up).

    focal = 0.5 * W / tan(0.5 * camera_angle_x)

The scenes are already normalised (object inside [-1.5, 1.5]^3, cameras at radius ~4),
so poses are used as they are. RGBA images are composited on a background colour. Every
problem with the data is reported as a `DataError` naming the file, before any compute
is spent.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.data.capture import (  # noqa: F401 (re-exported)
    Capture,
    Frame,
    SplitItem,
    no_data_folder,
    parse_split_spec,
    select,
)
from nerfkit.data.images import image_size, is_file, one_line
from nerfkit.rays.cameras import Camera


def is_blender(root: Path) -> bool:
    return any(Path(root).glob("transforms_*.json"))


def read_json(path: Path):
    """The JSON value in the file at path (a UTF-8 byte-order mark tolerated); a DataError naming the file when it
    cannot be read or parsed."""
    try:
        return json.loads(path.read_text(encoding="utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: not valid JSON ({one_line(e)}); fix or re-export the file") from None
    except RecursionError:
        raise DataError(f"{path}: not valid transforms JSON (nested too deeply); fix or re-export the file") from None
    except OSError as e:
        raise DataError(f"{path}: unreadable ({e.strerror})") from None


def read_transforms(root: Path, split: str) -> dict:
    """Read and check `root/transforms_{split}.json`."""
    path = root / f"transforms_{split}.json"
    if path.exists() and not path.is_file():
        raise DataError(f"{path}: is not a regular file; split {split!r} needs the transforms JSON there")
    if not path.is_file():
        have = sorted(p.name for p in root.glob("transforms_*.json"))
        hint = f" (found: {', '.join(have)})" if have else " (no transforms_*.json in that folder)"
        raise DataError(f"{path}: missing; split {split!r} needs this file{hint}")
    meta = read_json(path)
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
    if np.abs(pose).max() > 1e12:  # training works in float32 (to 3e38) and squares distances
        raise DataError(f"{where}: transform_matrix has values beyond 1e12; the capture's coordinates are broken")
    r = pose[:3, :3]
    # A camera-to-world rotation: orthonormal columns, det +1 (Blender exports are exact to ~1e-6).
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-3) or abs(np.linalg.det(r) - 1) > 1e-3:
        raise DataError(f"{where}: transform_matrix is not rigid (its 3x3 part is not a rotation)")
    if not np.allclose(pose[3], [0, 0, 0, 1], atol=1e-6):
        raise DataError(f"{where}: transform_matrix last row must be [0, 0, 0, 1]")
    return pose.astype(np.float32)


def frame_image_path(root: Path, file_path: str, where: str) -> Path:
    if "\x00" in file_path:
        raise DataError(f"{where}: file_path {file_path!r} contains a NUL character; fix the transforms JSON")
    p = root / file_path
    if p.suffix.lower() != ".png":
        with_png = p.with_name(p.name + ".png") if p.name else p
        if is_file(with_png) or not is_file(p):
            p = with_png
    if not is_file(p):
        raise DataError(f"{p}: missing image for {where}; fix its file_path or add the image")
    return p


def every_split(root: str | Path) -> str:
    """A spec naming every split a Blender scene has ("test,train,val"), from its transforms_{split}.json."""
    names = sorted(p.name[len("transforms_"):-len(".json")] for p in Path(root).glob("transforms_*.json"))
    return ",".join(names) or "train"


def read_blender(root: str | Path, spec: str) -> Capture:
    """The frames of the splits named in `spec`, as a Capture (only those JSON files are read)."""
    root = Path(root)
    splits, source = {}, {}
    for where, frame, pose, fov, split in iter_frames(root, ",".join(sorted({i.split for i in parse_split_spec(spec)}))):
        path = frame_image_path(root, frame["file_path"], where)
        w, h = image_size(path)
        cam = Camera.pinhole(w, h, 0.5 * w / math.tan(0.5 * fov))
        splits.setdefault(split, []).append(Frame(path, pose, cam, None, where))
        source[split] = str(root / f"transforms_{split}.json")
    return Capture(root, "blender", splits, normalize=False, alpha=True, own_splits=True, source=source)



def iter_frames(root: Path, spec: str):
    """Yield (where, frame dict, checked pose [4, 4], camera_angle_x, split) for every frame
    of a split spec, checking the folder, each transforms JSON, index ranges, poses, and that
    all splits share one field of view."""
    root = Path(root)
    if not root.is_dir():
        raise no_data_folder(root)
    fov = None
    for item in parse_split_spec(spec):
        meta = read_transforms(root, item.split)
        jpath = root / f"transforms_{item.split}.json"
        if fov is not None and abs(meta["camera_angle_x"] - fov) > 1e-6:
            raise DataError(f"{jpath}: camera_angle_x {meta['camera_angle_x']} differs from the other splits ({fov})")
        fov = float(meta["camera_angle_x"])
        frames = meta["frames"]
        for k in select(str(jpath), item, len(frames)):
            where = f"{jpath} frame {k}"
            yield where, frames[k], check_pose(frames[k]["transform_matrix"], where), fov, item.split


# -- the format (data/formats/registry.py) ----------------------------------------------------------
NAME = "blender"
LOOKS_FOR = "transforms_train.json"


def detect(root: Path) -> bool:
    return is_blender(root)


def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
    """Only the JSONs of the splits `spec` names are read; splits are the files' own (no holdout)."""
    return read_blender(root, spec)
