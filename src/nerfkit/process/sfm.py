"""Structure from motion with pycolmap: SIFT features, matching, incremental mapping.

    extract   SIFT on every photo (longest side at most max_image_size), one shared camera
              (COLMAP's SINGLE mode) of the chosen model, COLMAP feature masks where given
              (features only on the object: a turntable's still backdrop would lie about
              the motion)
    focal     COLMAP takes a focal-length prior from EXIF by itself; an implausible one
              (f / longest side outside [0.3, 5], e.g. photos downscaled without fixing
              their EXIF resolution) is replaced by COLMAP's own guess 1.2 x longest side,
              marked as no prior
    match     exhaustive (every pair) or sequential (each photo with its next 10 and
              quadratically farther ones; for video). COLMAP's loop detection needs a
              vocabulary tree file that is downloaded on first use, so it is not offered.
    map       incremental mapping; the model with the most registered photos is kept
    lens      OPENCV is estimated by mapping with SIMPLE_RADIAL (mapping directly with the
              4 distortion terms falls apart into many small models on narrow lenses), then
              one global bundle adjustment with OPENCV
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from nerfkit.rays.colmap_compat import pycolmap

CAMERA_MODELS = ("SIMPLE_RADIAL", "OPENCV", "PINHOLE")


@dataclass
class SfmOptions:
    camera_model: str = "SIMPLE_RADIAL"
    matching: str = "exhaustive"  # or "sequential"
    max_image_size: int = 1600
    threads: int = -1
    seed: int = 0
    verbose: bool = False


@contextlib.contextmanager
def colmap_log(path: Path, verbose: bool):
    """Send what COLMAP writes to stderr (glog, Ceres) into `path` (appended), unless verbose.

    glog writes to file descriptor 2 directly, so the descriptor itself is redirected."""
    if verbose:
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 2)
    os.close(fd)
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


def _fix_focal_prior(db_path: Path) -> list[str]:
    """Replace implausible EXIF focal priors (see module docstring); returns what was changed."""
    notes = []
    db = pycolmap.Database.open(str(db_path))
    try:
        for cam in db.read_all_cameras():
            side = max(cam.width, cam.height)
            ratio = cam.mean_focal_length() / side
            if cam.has_prior_focal_length and not 0.3 <= ratio <= 5.0:
                notes.append(f"EXIF focal length {cam.mean_focal_length():.0f} px for {side} px photos is implausible; "
                             f"using {1.2 * side:.0f} px as a starting guess")
                idx = set(cam.focal_length_idxs())
                cam.params = [1.2 * side if i in idx else p for i, p in enumerate(cam.params)]
                cam.has_prior_focal_length = False
                db.update_camera(cam)
    finally:
        db.close()
    return notes


def run_sfm(image_dir: Path, names: list[str], work: Path, opts: SfmOptions, mask_dir: Path | None, log: Path,
            stage=print):
    """Features, matches and the largest incremental model of photos `names` in image_dir.

    Returns (Reconstruction or None, {"extract": s, "match": s, "map": s, ...}, notes).
    `stage(text)` is called as each stage starts."""
    work.mkdir(parents=True, exist_ok=True)
    db_path = work / "database.db"
    if db_path.exists():
        db_path.unlink()  # extraction skips images already in a database
    times, notes = {}, []
    pycolmap.set_random_seed(opts.seed)
    stage(f"features: SIFT on {len(names)} photos")
    times["extract"] = extract(db_path, image_dir, names, opts, mask_dir, log)
    notes += _fix_focal_prior(db_path)
    stage(f"matching: {opts.matching}" + (f" ({len(names) * (len(names) - 1) // 2} pairs)"
                                          if opts.matching == "exhaustive" else ""))
    times["match"] = match(db_path, opts, log)
    stage("mapping: incremental")
    recs, times["map"] = incremental_map(db_path, image_dir, work / "models", opts, log)
    if not recs:
        return None, times, notes
    rec = max(recs.values(), key=lambda r: r.num_reg_images())
    if len(recs) > 1:
        notes.append(f"SfM found {len(recs)} separate models; kept the largest ({rec.num_reg_images()} photos)")
    if opts.camera_model == "OPENCV":
        stage("lens: OPENCV bundle adjustment")
        t = time.perf_counter()
        to_opencv(rec, log, opts.verbose)
        times["opencv"] = time.perf_counter() - t
    return rec, times, notes


def extract(db_path: Path, image_dir: Path, names: list[str], opts: SfmOptions, mask_dir: Path | None,
            log: Path, camera=None, per_image: bool = False) -> float:
    """SIFT features of photos `names` into the database (one shared camera of the mapping model: OPENCV is
    mapped as SIMPLE_RADIAL; COLMAP feature masks from mask_dir); returns the seconds it took. `camera`: a
    known camera (rays.cameras.Camera) every photo shares, its model and parameters as given; `per_image`: a
    camera per photo instead of one shared (triangulate.py, for photos of several known cameras).
    RuntimeError when the database did not keep every photo."""
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "SIMPLE_RADIAL" if opts.camera_model == "OPENCV" else opts.camera_model
    mode = pycolmap.CameraMode.PER_IMAGE if per_image else pycolmap.CameraMode.SINGLE
    if camera is not None:
        reader.camera_model, params = camera.colmap()
        reader.camera_params = ",".join(repr(p) for p in params)
    if mask_dir is not None:
        reader.mask_path = str(mask_dir)
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = opts.threads
    extraction.max_image_size = opts.max_image_size
    t = time.perf_counter()
    with colmap_log(log, opts.verbose):
        pycolmap.extract_features(str(db_path), str(image_dir), image_names=names,
                                  camera_mode=mode, reader_options=reader,
                                  extraction_options=extraction, device=pycolmap.Device.cpu)
    seconds = time.perf_counter() - t
    db = pycolmap.Database.open(str(db_path))
    n_db = db.num_images()
    db.close()
    if n_db != len(names):
        raise RuntimeError(f"feature extraction kept {n_db} of {len(names)} photos (see {log})")
    return seconds


def match(db_path: Path, opts: SfmOptions, log: Path) -> float:
    """Match the database's features, exhaustive or sequential (opts.matching; no loop detection), with
    seeded two-view verification; returns the seconds it took."""
    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = opts.threads
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = opts.seed
    t = time.perf_counter()
    with colmap_log(log, opts.verbose):
        if opts.matching == "exhaustive":
            pycolmap.match_exhaustive(str(db_path), matching_options=matching, verification_options=verification,
                                      device=pycolmap.Device.cpu)
        else:
            pairing = pycolmap.SequentialPairingOptions(overlap=10, quadratic_overlap=True)
            pairing.loop_detection = False  # needs a downloaded vocabulary tree
            pycolmap.match_sequential(str(db_path), matching_options=matching, pairing_options=pairing,
                                      verification_options=verification, device=pycolmap.Device.cpu)
    return time.perf_counter() - t


def incremental_map(db_path: Path, image_dir: Path, sparse: Path, opts: SfmOptions, log: Path):
    """({index: Reconstruction} of every model of 3 photos or more, written under `sparse` (emptied first),
    seconds it took): seeded incremental mapping of the matched database."""
    mapper = pycolmap.IncrementalPipelineOptions()
    mapper.num_threads = opts.threads
    mapper.multiple_models = True
    mapper.min_model_size = 3
    mapper.random_seed = opts.seed
    shutil.rmtree(sparse, ignore_errors=True)
    sparse.mkdir()
    t = time.perf_counter()
    with colmap_log(log, opts.verbose):
        recs = pycolmap.incremental_mapping(str(db_path), str(image_dir), str(sparse), options=mapper)
    return recs, time.perf_counter() - t


def to_opencv(rec, log: Path, verbose: bool) -> None:
    """SIMPLE_RADIAL (f, cx, cy, k) -> OPENCV (f, f, cx, cy, k, 0, 0, 0), then one global bundle adjustment."""
    for cid, cam in list(rec.cameras.items()):
        if cam.model_name == "SIMPLE_RADIAL":
            f, cx, cy, k = cam.params
            rec.cameras[cid] = pycolmap.Camera(camera_id=cid, model="OPENCV", width=cam.width, height=cam.height,
                                               params=[f, f, cx, cy, k, 0.0, 0.0, 0.0])
    ba = pycolmap.BundleAdjustmentOptions()
    ba.print_summary = False
    with colmap_log(log, verbose):
        pycolmap.bundle_adjustment(rec, ba)
