"""Points for a capture that has poses but no points (LLFF's poses_bounds.npy, a transforms.json without
sparse_pc.ply): structure from the given cameras, not from motion.

    features   SIFT on the training photos, as process-data extracts them (sfm.extract), with the
               capture's own camera model and intrinsics, and COLMAP feature masks where the frames have
               masks (points on the object only); photos under FEATURE_SIDE px are enlarged first
               (feature_upscale)
    match      every pair (sfm.match) up to EXHAUSTIVE_MAX photos, else each photo with its sequence
               neighbours (a video's frames)
    triangulate  COLMAP's triangulation with every camera and pose held as given
               (pycolmap.triangulate_points): tracks of at least two photos, merged and filtered by
               reprojection error as COLMAP's mapper does

Poses go in as COLMAP's cam_from_world (formats/colmap.cam_from_world: OpenCV axes, the inverse of the
capture's OpenGL c2w with y and z flipped); the points come back in the capture's own coordinates, the frame Capture.points is in.

Measured on maryrose (60 training photos at 864 px, 2 cores): features 19 s, matching 67 s (1770 pairs),
triangulation 3 s; 24,305 points at a mean reprojection error of 0.38 px. The result is kept in a cache
folder keyed by the photos, poses and cameras (cached_triangulation), so a second run on the capture, or
--resume, reads it back.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from nerfkit.data.capture import Frame
from nerfkit.data.formats.colmap import colmap_camera, colmap_pose
from nerfkit.data.images import load_mask
from nerfkit.data.points import read_points
from nerfkit.process.sfm import SfmOptions, colmap_log, extract, match
from nerfkit.rays.colmap_compat import pycolmap

EXHAUSTIVE_MAX = 80  # photos matched pair by pair (3160 pairs, ~2 minutes on 2 cores); more: sequential
FEATURE_SIDE = 800  # photos whose longer side is shorter are enlarged for SIFT (feature_upscale)
MAX_UPSCALE = 4


@dataclass
class Triangulated:
    """points [P, 3] (capture coordinates), colors [P, 3] in [0, 1], how many photos saw features, and
    the seconds each stage took ({"extract", "match", "triangulate"}; empty when read from the cache)."""

    points: np.ndarray
    colors: np.ndarray
    photos: int
    seconds: dict
    reprojection_px: float | None = None


def _names(frames: list[Frame]) -> tuple[Path, list[str]]:
    """The folder every photo lies under and each photo's path relative to it (COLMAP's image names)."""
    root = Path(os.path.commonpath([str(f.image.resolve().parent) for f in frames]))
    return root, [f.image.resolve().relative_to(root).as_posix() for f in frames]


def feature_upscale(camera) -> int:
    """The integer factor small photos are enlarged by (bicubic) before SIFT: ceil(FEATURE_SIDE / longer
    side), at most MAX_UPSCALE; 1 for photos of FEATURE_SIDE px or more. SIFT finds few features on small
    photos (its finest scale is fixed in pixels): 40 procedural photos of 96 px gave 58 points as they are,
    507 enlarged 2x and 609 enlarged 4x (reprojection error 0.31, 0.47 and 0.30 px of the photo). More of
    them are wrong there (repeated checkerboard corners matched along epipolar lines: 0.63 of them within
    1.5 px of a surface against 0.95), yet a splat run starts better from them (benchmarks/splat_start.py)."""
    return int(min(MAX_UPSCALE, max(1, -(-FEATURE_SIDE // max(camera.width, camera.height)))))


def _enlarged(frames: list[Frame], factor: int, folder: Path) -> list[Frame]:
    """Copies of frames whose photos (and masks) are enlarged `factor` times into folder, cameras scaled."""
    out = []
    for k, f in enumerate(frames):
        with Image.open(f.image) as im:
            size = (im.width * factor, im.height * factor)
            image = folder / f"{k:05d}_{f.image.stem}.png"
            im.convert("RGB").resize(size, Image.BICUBIC).save(image)
        mask = None
        if f.mask is not None:
            mask = folder / f"{k:05d}_{f.image.stem}_mask.png"
            alpha = load_mask(f.mask, (f.camera.width, f.camera.height), f.image)
            Image.fromarray(np.round(alpha * 255).astype(np.uint8)).resize(size, Image.NEAREST).save(mask)
        out.append(dataclasses.replace(f, image=image, mask=mask, camera=f.camera.scaled(factor)))
    return out


def _feature_masks(frames: list[Frame], names: list[str], folder: Path) -> Path | None:
    """COLMAP feature masks (folder/NAME.png, 0 = no features) of frames that have object masks."""
    if not any(f.mask is not None for f in frames):
        return None
    for f, name in zip(frames, names):
        size = (f.camera.width, f.camera.height)
        keep = np.ones(size[::-1], bool) if f.mask is None else load_mask(f.mask, size, f.image) > 0.5
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.where(keep, 255, 0).astype(np.uint8)).save(folder / f"{name}.png")
    return folder


def triangulate(frames: list[Frame], work: Path, log: Path, threads: int = -1, seed: int = 0,
                max_image_size: int = 1600) -> Triangulated:
    """Points triangulated from the photos of `frames` at their given cameras and poses (module doc); `work`
    holds COLMAP's database, `log` what COLMAP printed. RuntimeError when no point could be triangulated."""
    if len(frames) < 2:
        raise RuntimeError(f"triangulation needs at least 2 photos, got {len(frames)}")
    factor = feature_upscale(frames[0].camera)
    if factor > 1:
        (work / "enlarged").mkdir(exist_ok=True)
        frames = _enlarged(frames, factor, work / "enlarged")
    root, names = _names(frames)
    cams = [f.camera for f in frames]
    single = all(c == cams[0] for c in cams)
    opts = SfmOptions(camera_model=cams[0].colmap()[0], threads=threads, seed=seed,
                      max_image_size=max_image_size,
                      matching="exhaustive" if len(frames) <= EXHAUSTIVE_MAX else "sequential")
    db_path = work / "database.db"
    if db_path.exists():
        db_path.unlink()
    masks = _feature_masks(frames, names, work / "masks")
    pycolmap.set_random_seed(seed)
    seconds = {"extract": extract(db_path, root, names, opts, masks, log, camera=cams[0] if single else None,
                                  per_image=not single)}
    seconds["match"] = match(db_path, opts, log)
    t = time.perf_counter()
    by_name = dict(zip(names, frames))
    db = pycolmap.Database.open(str(db_path))
    rec = pycolmap.Reconstruction()
    images = db.read_all_images()
    for cam_id in sorted({im.camera_id for im in images}):
        cam = by_name[next(im for im in images if im.camera_id == cam_id).name].camera
        rec.add_camera_with_trivial_rig(colmap_camera(pycolmap, cam, cam_id))
    for im in images:
        rec.add_image_with_trivial_frame(pycolmap.Image(name=im.name, camera_id=im.camera_id, image_id=im.image_id),
                                         colmap_pose(pycolmap, by_name[im.name].c2w))
    db.close()
    (work / "model").mkdir(exist_ok=True)
    with colmap_log(log, False):
        rec = pycolmap.triangulate_points(rec, str(db_path), str(root), str(work / "model"))
    seconds["triangulate"] = time.perf_counter() - t
    if rec.num_points3D() == 0:
        raise RuntimeError(f"no point could be triangulated from {len(frames)} photos (see {log})")
    pts = list(rec.points3D.values())
    return Triangulated(np.array([p.xyz for p in pts], np.float64), np.array([p.color for p in pts]) / 255.0,
                        len(images), seconds, float(rec.compute_mean_reprojection_error()))


def _key(frames: list[Frame]) -> str:
    """A hash of what the points depend on: each photo's path, size and time, its mask's, pose and camera."""
    h = hashlib.sha256(f"features enlarged to {FEATURE_SIDE} px, at most {MAX_UPSCALE}x".encode())
    for f in frames:
        for p in (f.image, f.mask):
            st = None if p is None else p.stat()
            h.update(json.dumps([str(p), None if st is None else [st.st_size, st.st_mtime_ns]]).encode())
        h.update(np.asarray(f.c2w, np.float64).tobytes())
        h.update(repr(f.camera).encode())
    return h.hexdigest()[:24]


def cache_folder() -> Path | None:
    """Where triangulated points are kept: $NERFKIT_POINTS_CACHE (off: nowhere), default ~/.cache/nerfkit/points."""
    path = os.environ.get("NERFKIT_POINTS_CACHE", str(Path.home() / ".cache" / "nerfkit" / "points"))
    return None if path.strip().lower() in ("", "0", "off", "none") else Path(path)


def cached_triangulation(frames: list[Frame], say=print) -> tuple[Triangulated, Path | None]:
    """triangulate(frames), or the points an earlier call left in cache_folder() for the same photos, poses
    and cameras; (points, the .ply they are kept in, or None without a cache)."""
    folder = cache_folder()
    ply = None if folder is None else folder / f"triangulated_{_key(frames)}.ply"
    if ply is not None and ply.is_file():
        points, colors = read_points(ply)
        say(f"points: {len(points)} triangulated earlier from these {len(frames)} photos ({ply})")
        return Triangulated(points, colors, len(frames), {}), ply
    say(f"points: the capture has poses but no points; triangulating features of the {len(frames)} training "
        f"photos at their given poses (pycolmap; about 1.5 s a photo on 2 cores)")
    with tempfile.TemporaryDirectory(prefix="nerfkit-triangulate-") as tmp:
        work = Path(tmp)
        log = work / "colmap.log" if folder is None else folder / "colmap.log"  # kept where errors can name it
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)
        tri = triangulate(frames, work, log)
    took = sum(tri.seconds.values())
    say(f"points: {len(tri.points)} from {tri.photos} photos in {took:.0f} s (features "
        f"{tri.seconds['extract']:.0f} s, matching {tri.seconds['match']:.0f} s), mean reprojection error "
        f"{tri.reprojection_px:.2f} px")
    if ply is not None:
        part = ply.with_suffix(".part.ply")
        rgba = np.concatenate([np.round(tri.colors * 255), np.full((len(tri.colors), 1), 255)], 1).astype(np.uint8)
        trimesh.PointCloud(tri.points, colors=rgba).export(part)
        shutil.move(part, ply)
    return tri, ply
