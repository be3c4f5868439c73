"""The nerfstudio / instant-ngp capture format: one `transforms.json` beside the images.

    {"camera_model": "OPENCV", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "p1", "p2",
     "aabb_scale": 16,
     "frames": [{"file_path": "images/IMG_0001.JPG", "transform_matrix": [[4x4]],
                 "mask_path": "masks/IMG_0001.png"}, ...]}

Intrinsics live at the top level or per frame (a frame's own keys win). Instead of fl_x,
instant-ngp files may give `camera_angle_x` (horizontal field of view, radians):
fl_x = w / (2 tan(camera_angle_x / 2)); fl_y defaults to fl_x, cx, cy to the image centre.
camera_model: PINHOLE, SIMPLE_PINHOLE, OPENCV (k1, k2, p1, p2, and k3), OPENCV_FISHEYE
(k1..k4). `transform_matrix` is camera-to-world in the OpenGL convention, as in the
Blender scenes. `aabb_scale` (instant-ngp) is kept as a hint: 1 means the scene fits the
unit box (bounded). Splits: "train_filenames", "val_filenames", "test_filenames" (nerfstudio's, image
paths as in file_path) where the file has them, else every N-th frame held out (--holdout-every).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from nerfkit.core.errors import DataError
from nerfkit.data.capture import Capture, Frame, holdout_splits
from nerfkit.data.formats.blender import check_pose, read_json
from nerfkit.data.images import image_size, is_file
from nerfkit.data.points import read_points
from nerfkit.rays.cameras import Camera

_MODELS = ("OPENCV", "OPENCV_FISHEYE", "PINHOLE", "SIMPLE_PINHOLE")


def _number(d: dict, key: str, where: str):
    v = d.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise DataError(f"{where}: '{key}' must be a finite number, got {v!r}")
    return float(v)


def frame_camera(meta: dict, frame: dict, size: tuple[int, int], where: str) -> Camera:
    """Intrinsics of one frame (its own keys over the file's) for an image of `size` (w, h) on disk."""
    get = {k: _number(frame, k, where) if k in frame else _number(meta, k, where)
           for k in ("fl_x", "fl_y", "cx", "cy", "w", "h", "camera_angle_x", "camera_angle_y",
                     "k1", "k2", "k3", "k4", "p1", "p2")}
    model = frame.get("camera_model", meta.get("camera_model", "OPENCV"))
    if model not in _MODELS:
        raise DataError(f"{where}: camera_model {model!r} is not supported; use one of {', '.join(_MODELS)}")
    w_img, h_img = size
    w = get["w"] or w_img
    h = get["h"] or h_img
    fx = get["fl_x"]
    if fx is None and get["camera_angle_x"] is not None:
        fx = 0.5 * w / math.tan(0.5 * get["camera_angle_x"])
    if fx is None:
        raise DataError(f"{where}: no intrinsics (need 'fl_x' or 'camera_angle_x', at the top level or per frame); "
                        f"add the focal length in pixels")
    fy = get["fl_y"]
    if fy is None:
        fy = 0.5 * h / math.tan(0.5 * get["camera_angle_y"]) if get["camera_angle_y"] is not None else fx
    cx = get["cx"] if get["cx"] is not None else 0.5 * w
    cy = get["cy"] if get["cy"] is not None else 0.5 * h
    if fx <= 0 or fy <= 0:
        raise DataError(f"{where}: focal lengths must be positive (fl_x={fx}, fl_y={fy})")
    # The numbers describe a w x h image; an image stored at another size scales them.
    if abs(w_img / w - h_img / h) > 1e-3 * max(1.0, w_img / w):
        raise DataError(f"{where}: the image is {w_img}x{h_img} but the intrinsics describe {w:g}x{h:g} "
                        f"(another aspect ratio); fix 'w'/'h' or the image")
    s = w_img / w
    k = {n: get[n] or 0.0 for n in ("k1", "k2", "k3", "k4", "p1", "p2")}
    if model == "OPENCV_FISHEYE":
        params = (fx, fy, cx, cy, k["k1"], k["k2"], k["k3"], k["k4"])
        cam = Camera(int(round(w)), int(round(h)), fx, fy, cx, cy, "OPENCV_FISHEYE", params)
    elif model == "OPENCV" and any(k.values()):
        if k["k4"]:
            raise DataError(f"{where}: k4 of a perspective OPENCV camera has no COLMAP equivalent; "
                            f"re-calibrate with k1, k2, k3, p1, p2")
        if k["k3"]:
            params = (fx, fy, cx, cy, k["k1"], k["k2"], k["p1"], k["p2"], k["k3"], 0.0, 0.0, 0.0)
            cam = Camera(int(round(w)), int(round(h)), fx, fy, cx, cy, "FULL_OPENCV", params)
        else:
            params = (fx, fy, cx, cy, k["k1"], k["k2"], k["p1"], k["p2"])
            cam = Camera(int(round(w)), int(round(h)), fx, fy, cx, cy, "OPENCV", params)
    else:
        cam = Camera(int(round(w)), int(round(h)), fx, fy, cx, cy)
    return cam if s == 1 else cam.scaled(s, w_img, h_img)


def resolve_path(root: Path, rel: object, where: str, key: str) -> Path:
    """root / rel, trying .png / .jpg when rel has no extension; DataError if missing."""
    if not isinstance(rel, str) or "\x00" in rel:
        raise DataError(f"{where}: '{key}' must be a file path (string), got {rel!r}")
    p = root / rel
    if not is_file(p) and not p.suffix:
        for ext in (".png", ".jpg", ".jpeg", ".JPG", ".PNG"):
            if is_file(p.with_name(p.name + ext)):
                return p.with_name(p.name + ext)
    if not is_file(p):
        raise DataError(f"{p}: missing file for {where} ({key}); fix the path or add the file")
    return p


def read_meta(path: Path) -> dict:
    meta = read_json(path)
    if not isinstance(meta, dict) or not isinstance(meta.get("frames"), list) or not meta["frames"]:
        raise DataError(f"{path}: expected a JSON object with a non-empty 'frames' list")
    return meta


def read_nerfstudio(root: Path, holdout_every: int = 8, masks: bool = True) -> Capture:
    path = root / "transforms.json"
    meta = read_meta(path)
    frames = []
    for k, fr in enumerate(meta["frames"]):
        where = f"{path} frame {k}"
        if not isinstance(fr, dict) or "file_path" not in fr or "transform_matrix" not in fr:
            raise DataError(f"{where}: needs 'file_path' and 'transform_matrix'")
        img = resolve_path(root, fr["file_path"], where, "file_path")
        cam = frame_camera(meta, fr, image_size(img), where)
        mask = resolve_path(root, fr["mask_path"], where, "mask_path") if masks and "mask_path" in fr else None
        frames.append(Frame(img, check_pose(fr["transform_matrix"], where).astype(float), cam, mask, where))
    named = named_splits(root, meta, frames, path)
    pts, cols, ply = sfm_points(root, meta, path)
    return Capture(root, "nerfstudio", named or holdout_splits(frames, holdout_every), source={"all": str(path)},
                   hint="bounded" if meta.get("aabb_scale") == 1 else None, own_splits=named is not None,
                   points=pts, point_colors=cols, points_file=ply)


def sfm_points(root: Path, meta: dict, path: Path) -> tuple:
    """(points [P, 3], colours [P, 3], file) of the capture's SfM cloud: transforms.json's ply_file_path, else
    sparse_pc.ply beside it (nerfstudio's and process-data's layout); (None, None, None) without one."""
    for name in (meta.get("ply_file_path"), "sparse_pc.ply"):
        if isinstance(name, str) and name and (root / name).is_file():
            try:
                pts, cols = read_points(root / name)
            except (OSError, ValueError, KeyError) as e:
                raise DataError(f"{root / name}: not a readable point cloud ({e}); fix or remove it "
                                f"(named by {path})") from None
            return (pts, cols, str(root / name)) if len(pts) else (None, None, None)
    return None, None, None


SPLIT_KEYS = ("train", "val", "test")


def named_splits(root: Path, meta: dict, frames: list[Frame], path: Path) -> dict[str, list[Frame]] | None:
    """The splits that transforms.json names itself (nerfstudio's "train_filenames", "val_filenames",
    "test_filenames": image paths as in file_path), with "all" = every frame; None when it names none."""
    if not any(f"{k}_filenames" in meta for k in SPLIT_KEYS):
        return None
    by_path = {f.image.resolve(): f for f in frames}
    splits = {}
    for k in SPLIT_KEYS:
        names = meta.get(f"{k}_filenames", [])
        if not isinstance(names, list):
            raise DataError(f"{path}: '{k}_filenames' must be a list of image paths")
        chosen = []
        for name in names:
            f = by_path.get(resolve_path(root, name, f"{path} {k}_filenames", f"{k}_filenames").resolve())
            if f is None:
                raise DataError(f"{path}: {k}_filenames lists {name!r}, which is no frame's file_path; fix the list")
            chosen.append(f)
        if chosen:
            splits[k] = chosen
    return {**splits, "all": frames}


def camera_to_json(cam: Camera) -> dict:
    """transforms.json intrinsics of a camera (PINHOLE, OPENCV or OPENCV_FISHEYE keys).

    COLMAP's SIMPLE_RADIAL / RADIAL / OPENCV / FULL_OPENCV (k4..k6 = 0) are the same lens as
    nerfstudio's OPENCV with fewer terms; other models have no transforms.json form."""
    out = {"w": cam.width, "h": cam.height, "fl_x": cam.fx, "fl_y": cam.fy, "cx": cam.cx, "cy": cam.cy}
    if not cam.params or cam.model == "PINHOLE":
        return {"camera_model": "PINHOLE", **out}
    p = cam.params
    if cam.model == "OPENCV_FISHEYE":
        return {"camera_model": "OPENCV_FISHEYE", **out, "k1": p[4], "k2": p[5], "k3": p[6], "k4": p[7]}
    k = None
    if cam.model == "SIMPLE_RADIAL":
        k = {"k1": p[3]}
    elif cam.model == "RADIAL":
        k = {"k1": p[3], "k2": p[4]}
    elif cam.model == "OPENCV":
        k = {"k1": p[4], "k2": p[5], "p1": p[6], "p2": p[7]}
    elif cam.model == "FULL_OPENCV" and not any(p[9:12]):
        k = {"k1": p[4], "k2": p[5], "p1": p[6], "p2": p[7], "k3": p[8]}
    if k is None:
        raise DataError(f"camera model {cam.model} has no transforms.json form; use --camera-model OPENCV, "
                        f"SIMPLE_RADIAL or PINHOLE")
    return {"camera_model": "OPENCV", **out, **{n: 0.0 for n in ("k1", "k2", "p1", "p2")}, **k}


def write_nerfstudio(path: Path, frames: list[dict], cameras: list[Camera], extra: dict | None = None) -> None:
    """Write transforms.json: frames are {"file_path", "transform_matrix" (4x4), optional "mask_path"};
    intrinsics go to the top level when all cameras are equal, else into each frame."""
    shared = all(c == cameras[0] for c in cameras)
    meta = dict(camera_to_json(cameras[0])) if shared else {}
    meta.update(extra or {})
    out = []
    for fr, cam in zip(frames, cameras):
        f = {"file_path": fr["file_path"], "transform_matrix": [list(map(float, r)) for r in fr["transform_matrix"]]}
        if fr.get("mask_path"):
            f["mask_path"] = fr["mask_path"]
        if not shared:
            f.update(camera_to_json(cam))
        out.append(f)
    meta["frames"] = out
    Path(path).write_text(json.dumps(meta, indent=2))


# -- the format (data/formats/registry.py) ----------------------------------------------------------
NAME = "nerfstudio"
LOOKS_FOR = "transforms.json"


def detect(root: Path) -> bool:
    return (Path(root) / "transforms.json").exists()


def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
    return read_nerfstudio(root, holdout_every, masks)
