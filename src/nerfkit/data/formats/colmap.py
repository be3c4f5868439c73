"""A COLMAP sparse model: `sparse/0/{cameras,images,points3D}.{bin,txt}` + `images/` (+ `masks/`).

Read with pycolmap. COLMAP stores world-to-camera poses in the OpenCV convention (x right,
y down, z forward); the OpenGL camera-to-world is the inverse with the y and z axes
negated. Every registered image becomes a frame (sorted by name) with its own camera
model (any COLMAP model: the lens is applied per pixel through pycolmap); the 3D points
come along for the scene bound.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.data.capture import Capture, Frame, holdout_splits
from nerfkit.data.formats.llff import attach_masks
from nerfkit.data.images import is_file
from nerfkit.rays.cameras import _from_pycolmap

OPENCV_TO_OPENGL = np.diag([1.0, -1.0, -1.0, 1.0])


def find_model(root: Path) -> Path | None:
    """The sparse model folder of a capture: sparse/0, sparse, or root itself."""
    for d in (root / "sparse" / "0", root / "sparse", root):
        if any(is_file(d / f"cameras.{ext}") for ext in ("bin", "txt")):
            return d
    return None


def c2w_from_cam_from_world(matrix_3x4: np.ndarray) -> np.ndarray:
    """OpenGL camera-to-world [4, 4] from a COLMAP cam_from_world [3, 4] (OpenCV axes)."""
    w2c = np.eye(4)
    w2c[:3] = matrix_3x4
    return np.linalg.inv(w2c) @ OPENCV_TO_OPENGL


def cam_from_world(c2w: np.ndarray) -> np.ndarray:
    """COLMAP's cam_from_world [3, 4] (OpenCV axes: x right, y down, z forward) of an OpenGL camera-to-world
    c2w [4, 4] (x right, y up, z backward): inverse(c2w @ diag(1, -1, -1, 1))[:3]; c2w_from_cam_from_world's
    inverse."""
    return np.linalg.inv(np.asarray(c2w, np.float64) @ OPENCV_TO_OPENGL)[:3]


MIN_RECORD_BYTES = 8  # every record of a binary model file (camera, image, point, ...) is at least this long


def check_binary_counts(model: Path) -> None:
    """DataError for a binary model file whose leading record count (uint64) cannot fit in the file: pycolmap
    would try to allocate that many records (a garbage count means minutes of swapping, then bad_alloc)."""
    for path in sorted(model.glob("*.bin")):
        size = path.stat().st_size
        if size < 8:
            raise DataError(f"{path}: truncated COLMAP model file ({size} bytes); re-export the model")
        with open(path, "rb") as f:
            count = int(np.frombuffer(f.read(8), "<u8")[0])
        if count > (size - 8) // MIN_RECORD_BYTES:
            raise DataError(f"{path}: not a COLMAP model file (it claims {count} records in {size} bytes); "
                            f"re-export the model")


def read_colmap(root: Path, holdout_every: int = 8, masks: bool = True) -> Capture:
    from nerfkit.rays.colmap_compat import (
        pycolmap,  # deferred: pycolmap loads only when a COLMAP model is read or written
    )

    model = find_model(root)
    if model is None:
        raise DataError(f"{root}: no COLMAP model (sparse/0/cameras.bin or .txt)")
    check_binary_counts(model)
    try:
        rec = pycolmap.Reconstruction(str(model))
    except Exception as e:  # noqa: BLE001 - pycolmap raises plain exceptions on bad files
        raise DataError(f"{model}: unreadable COLMAP model ({type(e).__name__}: {str(e).splitlines()[0][:160]}); "
                        f"re-export it") from None
    image_dir = root / "images"
    frames = []
    for img in sorted(rec.images.values(), key=lambda im: im.name):
        if not img.has_pose:
            continue
        where = f"{model} image {img.name}"
        path = image_dir / img.name
        if not is_file(path):
            raise DataError(f"{path}: missing image for {where}; put the photos in {image_dir}")
        c2w = c2w_from_cam_from_world(np.asarray(img.cam_from_world().matrix(), np.float64))
        frames.append(Frame(path, c2w, _from_pycolmap(rec.cameras[img.camera_id]), None, where))
    if not frames:
        raise DataError(f"{model}: no registered images in this model")
    attach_masks(root, frames, masks)
    pts = np.array([p.xyz for p in rec.points3D.values()], np.float64).reshape(-1, 3)
    cols = np.array([p.color for p in rec.points3D.values()], np.float32).reshape(-1, 3) / 255.0
    return Capture(root, "colmap", holdout_splits(frames, holdout_every), points=pts if len(pts) else None,
                   point_colors=cols if len(pts) else None, points_file=str(model) if len(pts) else None,
                   source={"all": str(model)})


def colmap_pose(pycolmap, c2w: np.ndarray):
    """The pycolmap.Rigid3d cam_from_world of an OpenGL camera-to-world c2w [4, 4] (pycolmap passed in: it
    loads only where a COLMAP model is written)."""
    m = cam_from_world(c2w)
    return pycolmap.Rigid3d(pycolmap.Rotation3d(m[:, :3]), m[:, 3])


def colmap_camera(pycolmap, camera, camera_id: int):
    """The pycolmap.Camera of a nerfkit Camera (its lens model and parameters, Camera.colmap) with id camera_id."""
    model, params = camera.colmap()
    return pycolmap.Camera(model=model, width=camera.width, height=camera.height, params=params, camera_id=camera_id)


def write_colmap(model_dir: Path, names: list[str], c2ws: np.ndarray, cameras: list, points: np.ndarray | None = None,
                 colors: np.ndarray | None = None, text: bool = True) -> Path:
    """A COLMAP sparse model (through pycolmap) of images `names` with OpenGL poses [N, 4, 4]
    and `cameras.Camera` intrinsics (identical cameras are shared); optional points [P, 3]."""
    from nerfkit.rays.colmap_compat import (
        pycolmap,  # deferred: pycolmap loads only when a COLMAP model is read or written
    )

    rec = pycolmap.Reconstruction()
    ids: dict = {}
    for k, (name, c2w, cam) in enumerate(zip(names, c2ws, cameras), 1):
        if cam not in ids:
            ids[cam] = len(ids) + 1
            rec.add_camera_with_trivial_rig(colmap_camera(pycolmap, cam, ids[cam]))
        rec.add_image_with_trivial_frame(pycolmap.Image(name=name, camera_id=ids[cam], image_id=k),
                                         colmap_pose(pycolmap, c2w))
    for k, p in enumerate(np.zeros((0, 3)) if points is None else points):
        c = np.full(3, 128, np.uint8) if colors is None else np.asarray(colors[k], np.uint8)
        rec.add_point3D(np.asarray(p, np.float64), pycolmap.Track(), c)
    model_dir = Path(model_dir)
    model_dir.mkdir(parents=True, exist_ok=True)
    (rec.write_text if text else rec.write_binary)(str(model_dir))
    return model_dir


# -- the format (data/formats/registry.py) ----------------------------------------------------------
NAME = "colmap"
LOOKS_FOR = "sparse/0/cameras.bin|txt"


def detect(root: Path) -> bool:
    return find_model(Path(root)) is not None


def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
    return read_colmap(Path(root), holdout_every, masks)
