"""The arguments of each `nerfkit` verb, as typed dataclasses that tyro parses (main.py and train.py call)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Literal

import tyro

from nerfkit.core.config import Config
from nerfkit.core.presets import DEFAULT_PRESET


@dataclasses.dataclass
class TrainArgs:
    """Train a radiance field on a capture folder and write a run folder."""

    data_dir: tyro.conf.Positional[Path]
    """Capture folder: Blender (transforms_{split}.json), nerfstudio (transforms.json), LLFF (poses_bounds.npy)
    or COLMAP (sparse/0); `nerfkit process-data` makes one from photos or a video."""
    out: Path
    """Run folder (config, metrics, plots, validation images, checkpoints)."""
    preset: str = DEFAULT_PRESET
    """Starting configuration: ngp (default) | seed | nerf | mipnerf | demo | tiny (see README)."""
    resume: bool = False
    """Continue the run in --out from its newest checkpoint (with its saved config)."""
    overwrite: bool = False
    """Start again in an --out that holds an earlier run: its run files are removed first."""
    progress: bool = True
    """Show a progress bar."""
    viewer: bool = False
    """Open the interactive viewer while training (it takes at most 10% of the wall time; stays open after)."""
    viewer_host: str = "127.0.0.1"
    """Address the viewer listens on (another host only when asked: anyone who reaches it sees the scene)."""
    viewer_port: int = 7007
    """Viewer port (the next free one if taken; the address is printed)."""
    cfg: tyro.conf.OmitArgPrefixes[Config] = dataclasses.field(default_factory=Config)


@dataclasses.dataclass
class EvalArgs:
    """PSNR and SSIM of a trained run on a split; writes RUN_DIR/eval_<split>.json."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    data: Path | None = None
    """The data folder the views come from (default: the one the run was trained on)."""
    split: str = "test"
    """Views to evaluate: 'split' or 'split[a:b]', e.g. 'val[50:100]'."""
    downscale: int | None = None
    """Image downscale factor (default: the run's training resolution)."""
    every: int = 1
    """Evaluate every K-th view."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""
    baked: Path | None = None
    """Score this baked scene (nerfkit bake RUN --out DIR) instead of the field; writes eval_<split>_baked.json."""
    fit_poses: int = 0
    """Splat runs: first fit each view's pose to its photo against the frozen scene, at most N Levenberg-Marquardt
    iterations (10 is plenty; BARF's test-time protocol: the score measures the scene, not the pose's error); writes
    eval_<split>_fitted.json. 0: off."""
    fit_colour: bool = False
    """Fit each view's colour to its photo (an affine colour map, least squares on the photo's left half) and score
    the right half only: for photos whose exposure or white balance no training photo shares (NeRF-W's protocol);
    with --fit-poses the colour is solved alongside the pose. Writes eval_<split>_colour.json."""
    overwrite: bool = False
    """Replace this split's earlier evaluation (eval_<split>.json and its images)."""


@dataclasses.dataclass
class RenderArgs:
    """Render a split's poses or an orbit: RGB and depth PNGs, depth .npy, MP4 videos."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    data: Path | None = None
    """The data folder (poses, field of view, the orbit's path); default: the one the run was trained on."""
    split: str | None = None
    """Render the poses of this split, e.g. 'val[50:100]'."""
    orbit: int | None = None
    """Render an orbit of N frames: a circle at the cameras' typical radius and elevation (Blender scenes),
    or an ellipse fitted to the camera centres (photo captures), looking at the scene centre."""
    width: int | None = None
    """Output width in pixels, 2-8192 (default: training width, for --orbit at most 512; height follows the
    aspect ratio)."""
    height: int | None = None
    """Output height in pixels, 2-8192."""
    out: Path | None = None
    """Output folder (default: RUN_DIR/renders/<split-or-orbit>_<W>x<H>)."""
    camera_path: Path | None = None
    """Render a camera path: nerfstudio's camera_path.json layout (written by `nerfkit view` or nerfstudio's
    viewer); its frames, field of view, resolution and fps unless --width/--height/--fps are given."""
    fps: int | None = None
    """Video frame rate, 1-240 (default: the camera path's, else 24)."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""
    overwrite: bool = False
    """Render into an output folder that is not empty (files of the same names are replaced)."""


@dataclasses.dataclass
class BakeArgs:
    """Distil a trained fast field (bounded scenes) into a sparse brick grid of density and spherical-harmonics
    colour plus a WebGL2 page that renders it in any browser (nerfkit-baked-v1, see src/nerfkit/models/baked/format.py);
    score it with nerfkit eval RUN --baked DIR, open it with nerfkit view --baked DIR."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train` (fast field, bounded scene)."""
    out: Path
    """Folder to write the baked scene into (new or empty; --overwrite replaces a baked scene there)."""
    resolution: int | None = None
    """Grid cells per axis of the scene box (a multiple of 8); default: 256, or the finest of 224, 192, ...
    whose bake fits --max-mb."""
    sh_bands: int = 2
    """Spherical-harmonics bands of the view-dependent colour: 1 (diffuse), 2 or 3 (3 doubles the size)."""
    finetune_minutes: float = 2.0
    """Optimise the baked values against the training images for this long (0: no fine-tuning)."""
    max_mb: float = 50.0
    """Size budget in MB: fail before writing when the bake would be larger (lower --resolution or --sh-bands)."""
    progress: bool = True
    """Show progress bars."""
    overwrite: bool = False
    """Replace the baked scene in --out if there is one."""


@dataclasses.dataclass
class ImportSplatArgs:
    """A splat file made anywhere (.ply in the Inria layout from gsplat, 3DGS, Brush, SuperSplat or nerfkit; .spz;
    .splat; .glb / .gltf with KHR_gaussian_splatting; PlayCanvas's .sog) as a run folder: nerfkit view, render, bake and export then work on it; with --data, eval scores it on
    that capture's photos and train --resume fine-tunes it."""

    file: tyro.conf.Positional[Path]
    """The splat file (.ply, .spz, .splat, .glb, .gltf or .sog)."""
    out: Path
    """The run folder to write."""
    data: Path | None = None
    """The capture the file was made from, in the same coordinates (the COLMAP model's or poses' frame): the run
    takes its cameras and normalisation. Without it, the import makes RUN/capture: the file's own renders from
    16 cameras on an orbit around it."""
    overwrite: bool = False
    """Replace an earlier run in --out."""


@dataclasses.dataclass
class ViewArgs:
    """Interactive viewer in the browser (viser): orbit / fly, RGB / depth / opacity, the training cameras,
    saved views and camera paths (render them with `nerfkit render RUN --camera-path FILE`)."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train`."""
    port: int = 7007
    """Port (the next free one if taken; the address is printed)."""
    host: str = "127.0.0.1"
    """Address to listen on; 0.0.0.0 makes the viewer reachable from other machines (a warning is printed)."""
    chunk: int | None = None
    """Rays per rendering chunk (default: the run's --chunk)."""


@dataclasses.dataclass
class ViewBakedArgs:
    """Serve a baked scene's WebGL page (nerfkit bake RUN --out DIR) and print its address."""

    baked: Path
    """A baked scene folder written by `nerfkit bake`."""
    port: int = 7007
    """Port (the next free one if taken; the address is printed)."""
    host: str = "127.0.0.1"
    """Address to listen on; 0.0.0.0 makes the page reachable from other machines (a warning is printed)."""


@dataclasses.dataclass
class MakeSceneArgs:
    """Write nerfkit's procedural demo scene in Blender format (with exact depth maps)."""

    out_dir: tyro.conf.Positional[Path]
    """Folder to write transforms_{train,val,test}.json and the images into."""
    size: int = 64
    """Image width and height in pixels."""
    n_train: int = 60
    """Training views."""
    n_val: int = 10
    """Validation views."""
    n_test: int = 10
    """Test views."""
    seed: int = 0
    """Seed of the camera poses."""
    overwrite: bool = False
    """Write into a folder that is not empty (files of the same names are replaced)."""


@dataclasses.dataclass
class MakeMultiscaleArgs:
    """Write a Blender-format scene at full, 1/2, 1/4, 1/8 resolution in mip-NeRF's multiscale layout
    (metadata.json with per-frame width, height, focal and lossmult; box-averaged images)."""

    data_dir: tyro.conf.Positional[Path]
    """A Blender-format scene (transforms_{split}.json + RGBA PNGs)."""
    out: Path
    """New folder for the multiscale scene."""
    levels: int = 4
    """Number of scales, each half the size of the one before."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class DemoArgs:
    """Generate the procedural scene, train on it, evaluate on its test views, render an orbit video."""

    out: Path = Path("nerfkit-demo")
    """Folder for the scene and the run."""
    preset: str = "demo"
    """Model preset to train."""
    max_minutes: float = 3.0
    """Training time budget."""
    max_steps: int | None = None
    """Stop after this many steps instead (with --max-minutes given too: whichever comes first)."""
    size: int = 256
    """Scene image size (training, evaluation and the orbit video)."""
    orbit_frames: int = 48
    """Frames in the orbit video."""
    overwrite: bool = False
    """Start again in an --out that holds an earlier demo (its scene and run are replaced)."""


@dataclasses.dataclass
class ExperimentArgs:
    """Run an experiment. pe-ablation: train Model-1 (PE, L_xyz=10, L_dir=4), Model-2 (no PE) and
    Model-3 (PE, L_xyz=5, L_dir=2) with the same preset, seed and budget; evaluate, render orbits;
    write results.md/.json, overlaid curves, image grids and OUT/report.html. antialias: train nerf,
    mipnerf, ngp and ngp --antialias on every scale of multiscale data (nerfkit make-multiscale) for
    --budget-minutes each; PSNR / SSIM per scale, per-scale grids and crops, OUT/report.html."""

    experiment: tyro.conf.Positional[Literal["pe-ablation", "antialias"]]
    """Which experiment: pe-ablation or antialias."""
    data_dir: tyro.conf.Positional[Path]
    """Folder with transforms_{split}.json and the images."""
    out: Path
    """Experiment folder (one run folder per model, results, plots, grids, report.html)."""
    budget_minutes: float | None = None
    """Wall-time budget per model, compile and validation included."""
    max_steps: int | None = None
    """Step budget per model (with --budget-minutes: whichever comes first)."""
    preset: str = "seed"
    """Configuration all three models start from (only the positional encoding differs)."""
    seed: int | None = None
    """Seed of all three models (default: the preset's)."""
    eval_every: int | None = None
    """Evaluate every K-th view of the val split (default: 2 for pe-ablation, 5 for antialias)."""
    orbit_frames: int = 40
    """Frames of each model's orbit video (at the training resolution)."""
    grid_views: int | None = None
    """Validation views shown in image grids (default: 2 for pe-ablation, 1 for antialias)."""
    val_every: int | None = None
    """Validate every N steps during training (default: the preset's)."""
    train_split: str | None = None
    """Frames to train on (default: the data's train split); the report's seed protocol is "train,val[0:50]"."""
    val_split: str | None = None
    """Frames to validate and evaluate on (default: val, else test); seed protocol: "val[50:100]"."""
    target_width: int | None = None
    """Shrink images to this width (seed protocol: 200)."""
    downscale: int | None = None
    """Shrink images by this factor (overrides --target-width)."""
    models: str | None = None
    """antialias: comma-separated subset of nerf, mipnerf, ngp, ngp_antialias (default: all four)."""
    mlp_size: Literal["small", "paper"] = "small"
    """antialias: size of the nerf and mipnerf MLPs. small: both D=4, W=128, 64 + 64 samples (CPU budgets);
    paper: D=8, W=256, NeRF 64 + 128 and mip-NeRF 128 + 128 samples."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class BenchmarkArgs:
    """Train and evaluate every scene folder under ROOT with one preset and budget (resumable: finished
    scenes with the same settings are reused, interrupted ones resumed); writes OUT/<scene>/ run folders and
    the table OUT/results.md, results.json and results.png; a failed scene is a row marked failed, exit 1."""

    root: tyro.conf.Positional[Path]
    """Folder holding scene folders (e.g. nerf_synthetic/, or captures made by process-data)."""
    out: Path | None = None
    """Benchmark folder (default: runs/benchmark_<ROOT name>_<preset>)."""
    preset: str = DEFAULT_PRESET
    """Model preset of every scene."""
    budget_minutes: float | None = None
    """Wall-time budget per scene (compile and validation included)."""
    max_steps: int | None = None
    """Step budget per scene (with --budget-minutes: whichever comes first)."""
    jobs: int = 1
    """Scenes trained at once, each in its own process (and on its own GPU where there are several)."""
    only: str | None = None
    """Only this scene folder (by name)."""
    eval_every: int = 1
    """Evaluate every K-th view of each scene's validation split."""
    overwrite: bool = False
    """Train again the scenes whose earlier result in --out has other settings (otherwise refused)."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class ProcessArgs:
    """Recover camera poses from photos or a video with structure from motion (pycolmap, on the CPU) and
    write a capture folder that `nerfkit train` reads: transforms.json, images/, images_2/, images_4/,
    masks/, sparse_pc.ply, cameras.png (check it), colmap.log."""

    kind: tyro.conf.Positional[Literal["images", "video"]]
    """images: a folder of photos; video: one video file."""
    source: tyro.conf.Positional[Path]
    """The folder of photos (.jpg, .png, ...) or the video file."""
    out: Path
    """The capture folder to write (built aside and renamed when complete)."""
    masks: Path | None = None
    """Folder of object masks named like the photos (any extension, optional _mask suffix; white = object):
    SfM then sees only the object (needed for turntable captures) and training uses them as alpha."""
    camera_model: Literal["SIMPLE_RADIAL", "OPENCV", "PINHOLE"] = "SIMPLE_RADIAL"
    """One camera shared by all photos: SIMPLE_RADIAL (f, cx, cy, k), OPENCV (fx, fy, cx, cy, k1, k2, p1,
    p2; mapped with SIMPLE_RADIAL, then refined) or PINHOLE."""
    matching: Literal["auto", "exhaustive", "sequential"] = "auto"
    """auto: exhaustive up to 150 photos, sequential beyond and for videos (no loop closure: COLMAP's needs a
    downloaded vocabulary tree)."""
    frames: int = 120
    """video: number of frames to keep."""
    max_image_size: int = 1600
    """SIFT runs on photos shrunk to this longest side (poses stay in full-size pixels)."""
    overwrite: bool = False
    """Replace --out if it exists."""
    verbose: bool = False
    """Show COLMAP's log (otherwise kept in OUT/colmap.log)."""
    progress: bool = True
    """Show progress bars."""


@dataclasses.dataclass
class ReportArgs:
    """Write a static HTML report that opens from disk: RUN_DIR/report.html for a run folder, or
    the experiment report for a folder written by `nerfkit experiment`."""

    run_dir: tyro.conf.Positional[Path]
    """A run folder written by `nerfkit train` (or an experiment folder)."""
