"""`nerfkit process-data`: from a folder of photos (or a video) to a capture folder.

    DATA/
      transforms.json      nerfstudio / instant-ngp layout: shared intrinsics (fl_x fl_y cx cy w h
                           camera_model k1 k2 p1 p2), frames[].file_path, transform_matrix
                           (camera-to-world, OpenGL), mask_path (with --masks)
      images/              the photos under their original names (frame_NNNNN.jpg for a video)
      images_2/ images_4/  the same, box-downscaled by 2 and 4
      masks/               NAME.png per photo (with --masks; white = object)
      sparse_pc.ply        the SfM points with their colours
      cameras.png          camera frustums and points from two sides: did SfM work?
      colmap/sparse/0/     the COLMAP model (readable with --format colmap)
      colmap.log           what COLMAP said (shown live with --verbose)
      process.json         counts, timings, options

DATA is built in a hidden sibling folder (.DATA.incomplete) and renamed at the end, so a
DATA that exists is complete; a failed run leaves only the .incomplete folder, with its log.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm.auto import tqdm

from nerfkit.core.errors import DataError
from nerfkit.data.formats.colmap import c2w_from_cam_from_world
from nerfkit.data.formats.llff import find_mask, list_images
from nerfkit.data.formats.nerfstudio import write_nerfstudio
from nerfkit.data.images import check_one_size, image_size, load_mask, one_line
from nerfkit.process.plot import plot_cameras
from nerfkit.process.sfm import SfmOptions, run_sfm
from nerfkit.process.video import select_frames
from nerfkit.rays.cameras import _from_pycolmap

EXHAUSTIVE_UP_TO = 150


def _begin(out: Path, overwrite: bool) -> Path:
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())) and not overwrite:
        raise DataError(f"{out}: already exists; choose a new --out or pass --overwrite")
    tmp = out.parent / f".{out.name}.incomplete"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    return tmp


def _finish(tmp: Path, out: Path) -> None:
    if out.exists():
        shutil.rmtree(out) if out.is_dir() else out.unlink()
    os.replace(tmp, out)


def _copy_photos(photos: list[Path], tmp: Path, progress: bool) -> tuple[int, int]:
    """Check every photo decodes and all share one size; copy them and write images_2/, images_4/."""
    size = None
    for sub in ("images", "images_2", "images_4"):
        (tmp / sub).mkdir()
    for p in tqdm(photos, desc="copy photos", unit="img", disable=not progress):
        try:
            with Image.open(p) as im:
                im.load()
                rgb = im.convert("RGB")
        except Exception as e:  # noqa: BLE001 - Pillow raises many unrelated types on corrupt files
            raise DataError(f"{p}: unreadable photo ({type(e).__name__}: {one_line(e)}); remove it or "
                            f"re-export it as JPEG or PNG") from None
        if size is None:
            size = rgb.size
        elif rgb.size != size:
            raise DataError(f"{p}: photo is {rgb.size[0]}x{rgb.size[1]} but earlier photos are {size[0]}x{size[1]}; "
                            f"one shared camera needs one size (rotate or crop them alike)")
        shutil.copy2(p, tmp / "images" / p.name)
        for f in (2, 4):
            small = rgb.reduce(f)  # box average of f x f blocks
            small.save(tmp / f"images_{f}" / p.name, **({"quality": 95} if p.suffix.lower() in (".jpg", ".jpeg")
                                                        else {}))
    return size


def find_masks(photos: list[Path], masks: Path) -> list[Path]:
    """The mask of each photo (data/images.find_mask), checked from the files' headers before any work:
    DataError naming the first photo without a mask, or whose mask has another size."""
    if not masks.is_dir():
        raise DataError(f"{masks}: no such folder (--masks)")
    found = []
    for p in photos:
        m = find_mask(masks, p)
        if m is None:
            raise DataError(f"{masks}: no mask for {p.name} (looked for {p.stem}.*, {p.stem}_mask.*, {p.name}.png); "
                            f"masks are named like their photos, white = object")
        (w, h), (mw, mh) = image_size(p), image_size(m)
        if (w, h) != (mw, mh):
            raise DataError(f"{m}: mask is {mw}x{mh} but its image {p.name} is {w}x{h}; masks must have their "
                            f"image's size")
        found.append(m)
    return found


def _copy_masks(photos: list[Path], masks: Path, tmp: Path, size) -> Path:
    """DATA/masks/NAME.png (white = object) and COLMAP feature masks (DATA/colmap/masks/NAME.EXT.png, 0 = ignore)."""
    found = find_masks(photos, masks)
    (tmp / "masks").mkdir()
    colmap_masks = tmp / "colmap" / "masks"
    colmap_masks.mkdir(parents=True)
    for p, m in zip(photos, found):
        alpha = load_mask(m, size, p)
        Image.fromarray(np.round(alpha * 255).astype(np.uint8)).save(tmp / "masks" / f"{p.stem}.png")
        Image.fromarray(np.where(alpha > 0.5, 255, 0).astype(np.uint8)).save(colmap_masks / f"{p.name}.png")
    return colmap_masks


def _write_outputs(rec, tmp: Path, names: list[str], with_masks: bool) -> dict:
    """transforms.json, sparse_pc.ply, cameras.png and the COLMAP model of a reconstruction."""
    import trimesh

    regs = sorted((rec.image(i) for i in rec.reg_image_ids()), key=lambda im: im.name)
    frames, cams, c2ws = [], [], []
    for im in regs:
        c2w = c2w_from_cam_from_world(np.asarray(im.cam_from_world().matrix(), np.float64))
        cams.append(_from_pycolmap(rec.cameras[im.camera_id]))
        c2ws.append(c2w)
        frames.append({"file_path": f"images/{im.name}", "transform_matrix": c2w.tolist(),
                       "mask_path": f"masks/{Path(im.name).stem}.png" if with_masks else None})
    write_nerfstudio(tmp / "transforms.json", frames, cams)
    pts = np.array([p.xyz for p in rec.points3D.values()], np.float64).reshape(-1, 3)
    cols = np.array([p.color for p in rec.points3D.values()], np.uint8).reshape(-1, 3)
    if len(pts):
        rgba = np.concatenate([cols, np.full((len(cols), 1), 255, np.uint8)], 1)
        trimesh.PointCloud(pts, colors=rgba).export(tmp / "sparse_pc.ply")
    plot_cameras(tmp / "cameras.png", np.stack(c2ws), cams, pts, cols,
                 title=f"{len(regs)} of {len(names)} photos registered, {len(pts)} points")
    model = tmp / "colmap" / "sparse" / "0"
    model.mkdir(parents=True, exist_ok=True)
    rec.write(str(model))
    cam = cams[0]
    return {"registered": [im.name for im in regs], "points": int(len(pts)), "camera": cam.to_json()}


def process_images(src: Path, out: Path, masks: Path | None = None, opts: SfmOptions | None = None,
                   matching: str = "auto", overwrite: bool = False, progress: bool = True, log=print,
                   photos: list[Path] | None = None) -> dict:
    """Run the whole pipeline on the photos in `src` (or the given `photos`) and write DATA = out."""
    opts = opts or SfmOptions()
    src, out = Path(src), Path(out)
    photos = check_photos(src, photos, masks)
    if matching == "auto":
        matching = "exhaustive" if len(photos) <= EXHAUSTIVE_UP_TO else "sequential"
    opts.matching = matching
    t0 = time.perf_counter()
    tmp = _begin(out, overwrite)
    try:
        size = _copy_photos(photos, tmp, progress)
        colmap_masks = _copy_masks(photos, Path(masks), tmp, size) if masks is not None else None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    names = [p.name for p in photos]
    stages, stage = _stage_bar(4 if opts.camera_model != "OPENCV" else 5, progress)
    log_path = tmp / "colmap.log"
    rec, times, notes = run_sfm(tmp / "images", names, tmp / "colmap", opts, colmap_masks, log_path, stage)
    n_reg = 0 if rec is None else rec.num_reg_images()
    if n_reg < 3:
        stages.close()
        raise DataError(f"{src}: SfM registered {n_reg} of {len(photos)} photos, too few to train; "
                        f"{_advice(matching)} (COLMAP's log: {log_path})")
    stage("writing transforms.json, sparse_pc.ply, cameras.png")
    info = _write_outputs(rec, tmp, names, masks is not None)
    stages.update(1)
    stages.close()
    (tmp / "colmap" / "database.db").unlink(missing_ok=True)
    for sub in ("masks", "models"):
        shutil.rmtree(tmp / "colmap" / sub, ignore_errors=True)
    missing = sorted(set(names) - set(info["registered"]))
    summary = {"source": str(src.resolve()), "photos": len(photos), "registered": n_reg,
               "unregistered": missing, "points": info["points"], "camera": info["camera"],
               "matching": matching, "camera_model": opts.camera_model, "masks": masks is not None,
               "seconds": {k: round(v, 1) for k, v in times.items()} | {"total": round(time.perf_counter() - t0, 1)},
               "notes": notes}
    (tmp / "process.json").write_text(json.dumps(summary, indent=2))
    _finish(tmp, out)
    _say_result(summary, out, masks, log)
    return summary


def check_photos(src: Path, photos: list[Path] | None, masks: Path | None) -> list[Path]:
    """The photos to process (given, else those in the folder src), checked from their headers before any
    work: DataError for fewer than 3, photos of several sizes, or a missing or mis-sized mask."""
    if photos is None:
        if not src.is_dir():
            raise DataError(f"{src}: no such folder of photos")
        photos = list_images(src)
    if len(photos) < 3:
        raise DataError(f"{src}: {len(photos)} photos found (.jpg, .png, .tif, ...); SfM needs at least 3, "
                        f"ideally 30-150 with plenty of overlap")
    check_one_size([(p, image_size(p)) for p in photos], "photos", "one shared camera needs one size: rotate or "
                   "crop them alike")  # from the headers, before any photo is copied
    if masks is not None:
        find_masks(photos, Path(masks))
    return photos


def _stage_bar(n: int, progress: bool):
    """(a progress bar of n SfM stages, stage(text)): each call to stage completes the stage before it and
    shows text as the one running."""
    stages = tqdm(total=n, desc="sfm", unit="stage", disable=not progress,
                  bar_format="{desc}: {n}/{total} stages |{bar}| {elapsed} {postfix}")
    started = []

    def stage(text):
        if started:
            stages.update(1)
        started.append(text)
        stages.set_postfix_str(text)

    return stages, stage


def _say_result(summary: dict, out: Path, masks: Path | None, log) -> None:
    """The closing lines of process-data: notes, how many photos registered (and advice when under 90%), the
    camera, the photos left out, what was written."""
    n_reg, n, cam = summary["registered"], summary["photos"], summary["camera"]
    missing = summary["unregistered"]
    for note in summary["notes"]:
        log(f"note: {note}")
    frac = n_reg / n
    log(f"registered {n_reg} of {n} photos ({100 * frac:.0f}%) in {summary['seconds']['total'] / 60:.1f} min"
        f"; {summary['points']} points; camera {cam['model']} fx={cam['fx']:.1f}")
    if missing:
        log(f"not registered ({len(missing)}): {', '.join(missing[:20])}{' ...' if len(missing) > 20 else ''}")
    if frac < 0.9:
        log(f"only {100 * frac:.0f}% registered: {_advice(summary['matching'])}")
    log(f"wrote {out}: transforms.json, images/, images_2/, images_4/{', masks/' if masks else ''}, sparse_pc.ply, "
        f"cameras.png (look at it), colmap.log")


def _advice(matching: str) -> str:
    tips = ["take more photos with more overlap (every part seen from 3+ nearby angles)",
            "avoid plain, shiny or moving surfaces", "for an object on a turntable pass --masks"]
    if matching != "exhaustive":
        tips.append("try --matching exhaustive")
    return "; ".join(tips)


def process_video(video: Path, out: Path, n_frames: int = 120, masks: Path | None = None,
                  opts: SfmOptions | None = None, matching: str = "auto", overwrite: bool = False,
                  progress: bool = True, log=print) -> dict:
    """Sample `n_frames` sharp frames of a video (process/video.py), then as process_images
    (matching "auto" is sequential: video frames come in order)."""
    video, out = Path(video), Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())) and not overwrite:
        raise DataError(f"{out}: already exists; choose a new --out or pass --overwrite")
    frames = select_frames(video, n_frames, progress)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix=f".{out.name}.frames") as d:
        photos = []
        for k, rgb in frames:
            p = Path(d) / f"frame_{k:05d}.jpg"
            Image.fromarray(rgb).save(p, quality=95)
            photos.append(p)
        log(f"kept {len(photos)} frames of {video.name} (the sharper of each pair of evenly spaced frames)")
        return process_images(video, out, masks, opts, "sequential" if matching == "auto" else matching, overwrite,
                              progress, log, photos=photos)
