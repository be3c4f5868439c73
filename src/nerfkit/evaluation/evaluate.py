"""Using a trained run: evaluation on a split, and rendering poses or orbits to images/videos."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import re
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import ConfigError
from nerfkit.core.metrics import psnr, ssim
from nerfkit.core.outputs import check_new_folder, staged_folder
from nerfkit.core.viz import (
    background_rgb,
    colorize_renders,
    comparison,
    save_png,
    write_video,
)
from nerfkit.data.formats.multiscale import level_specs
from nerfkit.data.loader import load_frames, read_capture, scene_cameras
from nerfkit.data.normalize import undo_transform
from nerfkit.evaluation.colour import COLOUR_NOTE, colour_fitted
from nerfkit.models.baked.format import load_baked
from nerfkit.models import registry
from nerfkit.models.baked.model import BakedModel
from nerfkit.rays.camera_path import MAX_FPS, MAX_RENDER_SIZE, focal_from_fov_y, read_camera_path
from nerfkit.rays.cameras import Camera, ellipse_orbit_poses, orbit_poses
from nerfkit.render.images import check_chunk, check_every, make_renderer
from nerfkit.run.folder import RunFolder
from nerfkit.training.trainer import Trainer, TrainResult


def split_slug(spec: str) -> str:
    """A file-name-safe form of a split spec: "val[50:100]" -> "val_50_100"."""
    return re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]+", "_", spec)).strip("_")


def refuse_chunk(cfg, chunk: int | None) -> None:
    """ConfigError for --chunk on a run whose method renders whole images (rasterised Gaussian splats)."""
    if chunk is not None and registry.method_class(cfg).supports.renders_images:
        raise ConfigError("--chunk has no effect on this run: its method renders whole images (the tile rasteriser), "
                          "not ray chunks; drop it")


def appearance_note(cfg) -> str | None:
    """What held-out views are rendered with where training photos have an appearance of their own: the mean
    embedding (fields) or the mean colour transform (splats' --appearance); for their poses see pose_note."""
    if cfg.field.n_appearance():
        what = "embeddings"
    elif cfg.splat.appearance == "on":
        what = "colour transforms"
    else:
        return None
    return (f"appearance: the mean of the {cfg.field.appearance_count} training images' {what} "
            f"(held-out views have none of their own)")


POSE_NOTE = ("poses: the given ones moved with the training rig (the similarity that best maps the given training "
             "poses onto the refined ones; --pose-refine)")


FIT_NOTE = ("each view's pose fitted to its photo against the frozen scene before it is scored (at most {n} "
            "Levenberg-Marquardt iterations on the squared error from the pose above; --fit-poses): the score "
            "measures the scene, not the pose's error")


def check_fit_poses(steps: int) -> None:
    if steps < 0:
        raise ConfigError(f"--fit-poses must be 0 (off) or a number of iterations (10 is plenty), got {steps}")


def evaluate_run(run_dir: Path, data_dir: Path | None, split: str, downscale: int | None = None, every: int = 1,
                 chunk: int | None = None, progress: bool = True, checkpoint: Path | None = None,
                 write: bool = True, baked: Path | None = None, overwrite: bool = False, fit_poses: int = 0,
                 fit_colour: bool = False) -> dict:
    """PSNR and SSIM of every `every`-th view of `split`; writes RUN_DIR/eval_<split>.json and
    the renders (rgb beside ground truth, depth) under RUN_DIR/eval_<split>/ (unless not `write`).
    Multiscale data (data/formats/multiscale.py): every level is scored at its own size, and the mean
    over levels is the result (eval_<split>_multiscale.json, renders under .../d<level>/).
    `checkpoint`: evaluate that checkpoint instead of the newest. An earlier evaluation of the same split
    is replaced only with `overwrite` (else ConfigError before any work), once all new renders are written.
    `fit_poses` N > 0: each view's pose is first fitted to its photo (N iterations) against the frozen scene (BARF's
    test-time protocol; models whose supports.fit_poses), written to eval_<split>_fitted.json. `fit_colour`: each
    view's colour fitted on its photo's left half and the right half scored (colour.py; eval_<split>_colour.json)."""
    check_every(every)
    check_chunk(chunk)
    check_fit_poses(fit_poses)
    run_dir, folder = Path(run_dir), RunFolder(run_dir)
    trained = folder.load(checkpoint, scene=False)
    cfg, model, params, aux, step = trained.cfg, trained.model, trained.params, trained.aux, trained.step
    refuse_chunk(cfg, chunk)
    if baked is not None:
        scene = load_baked(baked)
        model = BakedModel(scene)
        (params, aux), step = model.params_and_aux(scene), scene.meta.get("step_trained", step)
    if fit_poses and not model.supports.fit_poses:
        raise ConfigError(f"--fit-poses: {'a baked scene' if baked is not None else model.title + ' runs'} cannot "
                          f"fit a view's pose (Gaussian splat runs can); drop --fit-poses")
    data_dir = folder.data_dir(data_dir)
    d = cfg.data
    cap = read_capture(data_dir, split, d.format, d.masks, d.holdout_every)
    renderer = make_renderer(model, cfg.train.chunk if chunk is None else chunk)
    levels = level_specs(cap, split)
    name = f"eval_{split_slug(split)}" + "".join(f"_{k}" for k, on in (("multiscale", levels is not None), (
        "baked", baked is not None), ("fitted", fit_poses), ("colour", fit_colour)) if on)
    if write and not overwrite and ((run_dir / f"{name}.json").exists() or (run_dir / name).exists()):
        raise ConfigError(f"{run_dir / (name + '.json')}: an earlier evaluation of {split} is there; pass --overwrite "
                          f"to replace it")
    bg = background_rgb(cfg.data.background)

    def score(spec, out_dir, ds, tw):
        data = load_frames(cap, spec, downscale=ds, target_width=tw, background=d.background, undistort=d.undistort)
        data = dataclasses.replace(data, poses=trained.seen_from(spec, data.poses, data_dir))
        return score_views(renderer, params, aux, data, every, progress, out_dir, bg, fit_poses, fit_colour), data

    with staged_folder(run_dir / name) if write else contextlib.nullcontext() as renders:  # all or none
        if levels is None:
            res, data = score(split, renders, downscale if downscale is not None else d.downscale,
                              None if downscale is not None else d.target_width)
            result = {"split": split, "step": step, "height": data.height, "width": data.width, **res}
        else:  # multiscale data: every level at its own size (--downscale shrinks them all further)
            scales = []
            for lvl, spec in levels:
                res, data = score(spec, renders / f"d{lvl}" if write else None, downscale or 1, None)
                scales.append({"level": lvl, "spec": spec, "height": data.height, "width": data.width, **res})
            result = multiscale_result(split, step, scales)
    result.update(result_notes(cfg, trained.refined_poses, fit_poses, baked, fit_colour))
    if write:
        (run_dir / f"{name}.json").write_text(json.dumps(result, indent=2))
        result["written"] = str(run_dir / f"{name}.json")
    return result


def multiscale_result(split: str, step: int, scales: list[dict]) -> dict:
    """The evaluation of multiscale data: the levels' results (each popped of its per_view rows) and their means."""
    return {"split": split, "step": step, "scales": scales, "n_views": sum(r["n_views"] for r in scales),
            "psnr": float(np.mean([r["psnr"] for r in scales])), "ssim": float(np.mean([r["ssim"] for r in scales])),
            "seconds_per_view": float(np.mean([r["seconds_per_view"] for r in scales])),
            "per_view": [{**v, "level": r["level"]} for r in scales for v in r.pop("per_view")]}


def result_notes(cfg, refined_poses: bool, fit_poses: int, baked: Path | None, fit_colour: bool = False) -> dict:
    """What an evaluation's JSON and table say about how its views were rendered and scored: appearance, poses,
    fitted poses, the baked scene, fitted colour."""
    notes = {"appearance": appearance_note(cfg)} if appearance_note(cfg) else {}
    notes.update({"poses": POSE_NOTE} if refined_poses else {})
    notes.update({"fitted_poses": FIT_NOTE.format(n=fit_poses)} if fit_poses else {})
    notes.update({"baked": str(Path(baked).resolve())} if baked is not None else {})
    notes.update({"fitted_colour": COLOUR_NOTE} if fit_colour else {})
    return notes


def train_and_evaluate(data_dir: Path, run_dir: Path, cfg, every: int = 1, progress: bool = True,
                       resume: bool = False) -> tuple[TrainResult, object, dict]:
    """Train `cfg` on data_dir into run_dir (or resume it), then evaluate the result on the split the run
    validated on (every `every`-th view). Returns (the training result, the run's resolved config, the
    evaluation). KeyboardInterrupt when training was interrupted (its checkpoint is saved)."""
    res = Trainer(data_dir, run_dir, cfg, resume=resume, progress=progress).run()
    if res.interrupted:
        raise KeyboardInterrupt
    run_cfg = RunFolder(run_dir).config()
    # The evaluation of the run just trained (an earlier one, of a resumed run's checkpoint, is out of date).
    ev = evaluate_run(run_dir, data_dir, run_cfg.data.val_split, every=every, progress=progress, overwrite=True)
    return res, run_cfg, ev


def score_views(renderer, params, aux, data, every: int, progress: bool, out_dir: Path | None, bg,
                fit_poses: int = 0, fit_colour: bool = False) -> dict:
    """PSNR / SSIM of every `every`-th view of `data` (per view and mean); the renders (rgb, depth,
    rgb beside ground truth, depth .npy) go to out_dir when given. fit_poses N > 0: each view is rendered from its
    pose fitted to its photo (renderer.fit_pose, N iterations), and how far the pose moved is in its row.
    fit_colour: each render's colour fitted on its photo's left half, the right half scored (colour.py; with
    fit_poses the pose is fitted with the photo's colour solved alongside)."""
    if min(data.height, data.width // (2 if fit_colour else 1)) < 3:  # SSIM's window
        raise ConfigError(f"the photos are {data.width}x{data.height} px at this scale, too small to score (at least "
                          f"{3 * (2 if fit_colour else 1)}x3); use a smaller --downscale")
    per_view, renders = [], []
    ids = list(range(0, len(data), every))
    t0 = time.perf_counter()
    for k in tqdm(ids, desc="eval", disable=not progress, unit="view"):
        c2w, moved = data.poses[k], {}
        if fit_poses:
            c2w, moved = renderer.fit_pose(params, aux, c2w, data.cameras[k], data.images[k], fit_poses,
                                           fit_colour=fit_colour)
            moved = {"pose_fit": {"degrees": moved["degrees"], "shift": moved["shift"] / data.scale}}
        r = renderer.render_camera(params, aux, c2w, data.cameras[k])
        if fit_colour:  # the render as scored: its colour fitted on the photo's left half
            r["rgb"], scores = colour_fitted(r, data.images[k], bg)
        else:
            scores = {"psnr": psnr(r["rgb"], data.images[k]), "ssim": ssim(r["rgb"], data.images[k])}
        per_view.append({"view": k, "name": data.names[k], **scores, **moved})
        renders.append(r)
    seconds = time.perf_counter() - t0
    depth_imgs, (lo, hi) = colorize_renders(renders, bg)
    for k, r, depth_img, v in zip(ids, renders, depth_imgs, per_view) if out_dir is not None else ():
        save_png(out_dir / f"view_{k:03d}_rgb.png", r["rgb"])
        save_png(out_dir / f"view_{k:03d}_depth.png", depth_img)
        save_png(out_dir / f"view_{k:03d}.png", comparison(data.images[k], r["rgb"], depth_img, lo / data.scale,
                                                           hi / data.scale, v["psnr"], background=bg))
        np.save(out_dir / f"view_{k:03d}_depth.npy", (r["depth"] / data.scale).astype(np.float32), allow_pickle=False)
    return {"n_views": len(ids), "psnr": float(np.mean([v["psnr"] for v in per_view])),
            "ssim": float(np.mean([v["ssim"] for v in per_view])), "seconds_per_view": seconds / max(len(ids), 1),
            "per_view": per_view, "worst": worst_views(per_view), "outlier_db": OUTLIER_DB}


OUTLIER_DB = 3.0  # a view this far below the median PSNR is pointed out


def worst_views(per_view: list[dict], k: int = 3) -> list[dict]:
    """The k lowest-scoring views (view, name, psnr), each marked "outlier" when more than OUTLIER_DB below
    the median: a photo to look at (a moving object, a mask that leaves part out, blur)."""
    if not per_view:
        return []
    median = float(np.median([v["psnr"] for v in per_view]))
    low = sorted(per_view, key=lambda v: v["psnr"])[:k]
    return [{"view": v["view"], "name": v["name"], "psnr": v["psnr"], "outlier": v["psnr"] < median - OUTLIER_DB}
            for v in low]


def format_eval_table(result: dict) -> str:
    lines = [f"{'view':>5}  {'name':<28} {'PSNR':>7} {'SSIM':>7}"]
    for v in result["per_view"]:
        lines.append(f"{v['view']:>5}  {v['name'][-28:]:<28} {v['psnr']:7.2f} {v['ssim']:7.4f}")
    for r in result.get("scales", ()):
        what = f"(level {r['level']}: {r['n_views']} views, {r['width']}x{r['height']})"
        lines.append(f"{'d' + str(r['level']):>5}  {what:<28} {r['psnr']:7.2f} {r['ssim']:7.4f}")
    lines.append(f"{'mean':>5}  {'(' + str(result['n_views']) + ' views, step ' + str(result['step']) + ')':<28} "
                 f"{result['psnr']:7.2f} {result['ssim']:7.4f}")
    if result.get("appearance"):
        lines.append(result["appearance"])
    if result.get("poses"):
        lines.append(result["poses"])
    if result.get("fitted_poses"):
        moved = [v["pose_fit"] for v in result["per_view"] if "pose_fit" in v]
        lines.append(result["fitted_poses"] + (f"; they moved a median {np.median([m['degrees'] for m in moved]):.3f} "
                                               f"degrees and {np.median([m['shift'] for m in moved]):.4g} units"
                                               if moved else ""))
    if result.get("fitted_colour"):
        before = [v["colour_fit"]["psnr_unfitted"] for v in result["per_view"] if "colour_fit" in v]
        lines.append(result["fitted_colour"] + (f"; the right halves scored {np.mean(before):.2f} dB before the "
                                                f"colour map" if before else ""))
    worst = result.get("worst") or worst_views(result["per_view"])
    if len(result["per_view"]) > 1 and worst:
        lines.append("worst views: " + ", ".join(f"{w['view']} {Path(w['name']).name} {w['psnr']:.2f} dB"
                                                 + (" (outlier)" if w["outlier"] else "") for w in worst))
        if any(w["outlier"] for w in worst):
            lines.append(f"outlier: more than {OUTLIER_DB:g} dB below the median view; look at that photo (something "
                         f"that moved, a mask that leaves part out, blur) in the eval folder")
    return "\n".join(lines)


ORBIT_MAX_WIDTH = 512  # orbits without --width/--height are rendered at most this wide
MIN_RENDER_SIZE = 2  # pixels a side: the videos' yuv420p stores colour at half resolution


def render_run(run_dir: Path, data_dir: Path | None, split: str | None = None, orbit: int | None = None,
               width: int | None = None, height: int | None = None, out: Path | None = None,
               fps: int | None = None, chunk: int | None = None, progress: bool = True,
               camera_path: Path | None = None, overwrite: bool = False) -> dict:
    """Render a split's poses, an N-frame orbit or a camera path (nerfstudio's camera_path.json)
    at any resolution: RGB and colour-mapped depth PNGs, depth as float32 .npy (sum_i w_i t_i),
    and an MP4 of each."""
    check_render_request(split, orbit, camera_path, chunk, width, height, fps)
    path = read_camera_path(camera_path) if camera_path is not None else None  # a bad file: before the run loads
    run_dir = Path(run_dir)
    folder = RunFolder(run_dir)
    trained = folder.load()
    cfg, model, params, aux, step = trained.cfg, trained.model, trained.params, trained.aux, trained.step
    refuse_chunk(cfg, chunk)
    data_dir = folder.data_dir(data_dir)
    scene = trained.scene
    d = cfg.data
    cap = read_capture(data_dir, cfg.data.train_split if split is None else split, d.format, d.masks, d.holdout_every)
    sel, poses, name = poses_to_render(cap, d, split, orbit, camera_path, path)
    if path is not None and width is None and height is None:
        width, height = path["width"], path["height"]
    cam0 = sel.cameras[0]
    aspect = cam0.height / cam0.width if path is None else path["height"] / path["width"]
    width, height, capped = output_size(width, height, aspect, scene, orbit)
    if max(width, height) > MAX_RENDER_SIZE:  # one side given, the other following the aspect ratio
        raise ConfigError(f"at this aspect ratio that is {width}x{height} pixels, more than {MAX_RENDER_SIZE} a side; "
                          f"give a smaller --width / --height")
    if min(width, height) < MIN_RENDER_SIZE:
        raise ConfigError(f"at this aspect ratio that is {width}x{height} pixels, under {MIN_RENDER_SIZE} a side "
                          f"(the videos' colour format needs {MIN_RENDER_SIZE}); give a larger --width / --height")
    cams, fps = render_cameras(sel, path, split, len(poses), width, height, fps)
    out = check_new_folder(Path(out) if out is not None else run_dir / "renders" / f"{name}_{width}x{height}",
                           overwrite)
    renderer = make_renderer(model, cfg.train.chunk if chunk is None else chunk)
    renders = []
    t0 = time.perf_counter()
    for k in tqdm(range(len(poses)), desc="render", disable=not progress, unit="view"):
        renders.append(renderer.render_camera(params, aux, poses[k], cams[k]))
    seconds = time.perf_counter() - t0
    with staged_folder(out) as tmp:  # a disk that fills half way leaves out as it was
        lo, hi = write_frames(tmp, renders, sel.scale, background_rgb(cfg.data.background), fps)
        info = {"out": str(out), "frames": len(poses), "width": width, "height": height, "step": step,
                "seconds_per_frame": seconds / len(poses), "depth_range": [lo / sel.scale, hi / sel.scale],
                "depth_units": "z-depth in the capture's own units", "camera": cams[0].to_json(),
                "width_capped_from": scene["width"] if capped else None,
                "camera_to_world": capture_poses(sel, poses)}
        (tmp / "render.json").write_text(json.dumps(info, indent=2))
    return info


def check_render_request(split: str | None, orbit: int | None, camera_path: Path | None, chunk: int | None,
                         width: int | None, height: int | None, fps: int | None) -> None:
    """ConfigError unless exactly one of split, orbit and camera_path is given, the sizes are
    MIN_RENDER_SIZE-MAX_RENDER_SIZE and the fps (when given) 1-MAX_FPS."""
    if sum(x is not None for x in (split, orbit, camera_path)) != 1:
        raise ConfigError("pass exactly one of --split SPLIT, --orbit N or --camera-path FILE")
    check_chunk(chunk)
    if orbit is not None and orbit < 1:
        raise ConfigError(f"--orbit must be >= 1 frames (got {orbit})")
    for name, v in (("--width", width), ("--height", height)):
        if v is not None and not MIN_RENDER_SIZE <= v <= MAX_RENDER_SIZE:
            raise ConfigError(f"{name} must be {MIN_RENDER_SIZE}-{MAX_RENDER_SIZE} pixels (got {v}; the videos' "
                              f"colour format needs {MIN_RENDER_SIZE} a side)")
    if fps is not None and not 1 <= fps <= MAX_FPS:
        raise ConfigError(f"--fps must be 1-{MAX_FPS} frames a second (got {fps})")


def poses_to_render(cap, d, split: str | None, orbit: int | None, camera_path: Path | None, path: dict | None):
    """(the cameras of the split the poses come from, camera-to-world poses [F, 4, 4], the output's name): the
    split's own poses, the camera path's, or an orbit around the training cameras (a circle for Blender
    scenes, else an ellipse fitted to the camera centres). d: the run's DataConfig."""
    if split is not None:
        sel = scene_cameras(cap, split, d.downscale, d.target_width, d.undistort)
        return sel, sel.poses, split_slug(split)
    train = scene_cameras(cap, d.train_split, d.downscale, d.target_width, d.undistort)
    if path is not None:
        return train, path["c2w"].astype(np.float32), f"path_{split_slug(Path(camera_path).stem)}"
    poses = orbit_poses(train.poses, orbit) if cap.format == "blender" else ellipse_orbit_poses(
        train.poses, orbit, center=np.zeros(3))
    return train, poses, f"orbit{orbit}"


def output_size(width: int | None, height: int | None, aspect: float, scene: dict,
                orbit: int | None) -> tuple[int, int, bool]:
    """(width, height, capped): the size asked for, the missing side following the aspect ratio (height /
    width); neither given: the run's training size, for an orbit at most ORBIT_MAX_WIDTH wide (capped)."""
    if width is None and height is None:
        width, height = scene["width"], scene["height"]
        if orbit is not None and width > ORBIT_MAX_WIDTH:  # a preview video: minutes, not an hour, on a CPU
            return ORBIT_MAX_WIDTH, max(1, round(ORBIT_MAX_WIDTH * aspect)), True
    elif width is None:
        width = max(1, round(height / aspect))
    elif height is None:
        height = max(1, round(width * aspect))
    return width, height, False


def render_cameras(sel, path: dict | None, split: str | None, n: int, width: int, height: int,
                   fps: int | None) -> tuple[list[Camera], int]:
    """(one camera per frame of n, the video's fps): a split's cameras (resized unless the size is theirs); a
    camera path's own field of view per frame (vertical, principal point at the centre) and fps; or the first
    training camera, resized, for every orbit frame. fps: given, else the path's, else 24."""
    cam0 = sel.cameras[0]
    native = split is not None and (width, height) == (cam0.width, cam0.height)
    cams = sel.cameras if native else [c.with_size(width, height) for c in sel.cameras]
    if path is not None:  # the path's own field of view (vertical, degrees), principal point at the centre
        cams = [Camera(width, height, f, f, 0.5 * width, 0.5 * height)
                for f in (focal_from_fov_y(v, height) for v in path["fov_y"])]
        fps = fps or path["fps"]
    elif split is None:
        cams = [cams[0]] * n
    return cams, fps or 24


def write_frames(out: Path, renders: list[dict], scale: float, bg, fps: int) -> tuple[float, float]:
    """OUT/rgb_K.png, depth_K.png (colour-mapped over the frames' common depth range), depth_K.npy (in the
    capture's units: depth / scale) and rgb.mp4, depth.mp4; returns that depth range (lo, hi), normalised."""
    depth_frames, (lo, hi) = colorize_renders(renders, bg)
    for k, (r, depth_img) in enumerate(zip(renders, depth_frames)):
        save_png(out / f"rgb_{k:04d}.png", r["rgb"])
        save_png(out / f"depth_{k:04d}.png", depth_img)
        np.save(out / f"depth_{k:04d}.npy", (r["depth"] / scale).astype(np.float32), allow_pickle=False)
    write_video(out / "rgb.mp4", [r["rgb"] for r in renders], fps=fps)
    write_video(out / "depth.mp4", depth_frames, fps=fps)
    return lo, hi


def capture_poses(sel, poses) -> list:
    """Camera-to-world of every frame in the capture's own coordinates (undoing the normalisation of sel)."""
    return undo_transform(sel.transform, sel.scale, np.asarray(poses)).tolist()
