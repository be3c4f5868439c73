"""`nerfkit import splat FILE --out RUN`: a splat file made anywhere (.ply from gsplat, 3DGS, Brush, SuperSplat or
nerfkit; .spz; .splat; .glb / .gltf; .sog) as a run folder, so that view, render, bake, export, eval and train
--resume work on it as on a trained run.

The run is what `nerfkit train CAPTURE --preset splat --init FILE --capacity N --max-steps 0` writes: the
file's Gaussians, moved into the capture's normalised frame, at step 0, with the capture's cameras and photos.

With --data CAPTURE that capture is the one the file was made from, in the same coordinates: eval then scores
the file on its photos and train --resume fine-tunes it there. Without one, the import makes a capture of the
file itself, RUN/capture (nerfstudio's transforms.json): ORBIT_VIEWS cameras (ORBIT_SIZE px square,
ORBIT_FOV_DEG field of view) circling the median of the Gaussians' centres at ORBIT_RADIUS times the distance
within which KEEP_SHARE of the centres lie, ORBIT_ELEVATION_DEG above the horizon with -y up (the capture
convention of the Inria .ply: COLMAP's frames have y down), and the file's own renders from them as photos.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.core.outputs import staged_folder
from nerfkit.core.presets import preset
from nerfkit.models.splat.formats import read_gaussians
from nerfkit.rays.cameras import Camera, look_at
from nerfkit.training.setup import clear_run, refuse_unfit_run_folder, run_files

ORBIT_VIEWS = 16
ORBIT_SIZE = 512
ORBIT_FOV_DEG = 50.0
ORBIT_RADIUS = 2.5  # times the distance from the centre within which KEEP_SHARE of the Gaussians lie
ORBIT_ELEVATION_DEG = 20.0
KEEP_SHARE = 0.9  # the share of the centres that sets the orbit's scale


def orbit_poses(means: np.ndarray, n: int = ORBIT_VIEWS) -> np.ndarray:
    """Camera-to-world poses [n, 4, 4] (capture coordinates) circling c, the per-axis median of the centres
    [N, 3], at ORBIT_RADIUS r (r: the KEEP_SHARE quantile of their distances to c), ORBIT_ELEVATION_DEG up
    (-y up), each looking at c."""
    means = np.asarray(means, np.float64)
    c = np.median(means, axis=0)
    r = max(float(np.quantile(np.linalg.norm(means - c, axis=1), KEEP_SHARE)), 1e-6)
    el = math.radians(ORBIT_ELEVATION_DEG)
    poses = []
    for k in range(n):
        az = 2 * math.pi * k / n
        eye = c + ORBIT_RADIUS * r * np.array([math.cos(el) * math.cos(az), -math.sin(el), math.cos(el) * math.sin(az)])
        poses.append(look_at(eye, c, up=np.array([0.0, -1.0, 0.0])))
    return np.stack(poses)


def write_orbit_capture(g: dict, degree: int, root: Path) -> Path:
    """RUN/capture: transforms.json with the orbit cameras (orbit_poses) and the Gaussians' renders from them
    (white background) as its photos. Returns root."""
    from imageio.v3 import imwrite

    from nerfkit.data.formats.nerfstudio import write_nerfstudio
    from nerfkit.models.splat.gaussians import render_frame

    focal = 0.5 * ORBIT_SIZE / math.tan(math.radians(ORBIT_FOV_DEG) / 2)
    camera = Camera.pinhole(ORBIT_SIZE, ORBIT_SIZE, focal)
    (root / "images").mkdir(parents=True, exist_ok=True)
    frames = []
    for k, pose in enumerate(orbit_poses(g["means"])):
        rgb = render_frame(g, pose, camera, (1.0, 1.0, 1.0), degree, depth=False)["rgb"]
        name = f"images/orbit_{k:03d}.png"
        imwrite(root / name, np.round(255 * rgb).astype(np.uint8))
        frames.append({"file_path": name, "transform_matrix": pose})
    write_nerfstudio(root / "transforms.json", frames, [camera] * len(frames))
    return root


def import_splat(file: Path, out: Path, data: Path | None = None, overwrite: bool = False, log=print) -> dict:
    """Make run folder `out` from splat file `file` (see the module docstring); refuses to replace an earlier run
    (or, without `data`, a capture/ folder in out) unless `overwrite`. The run is made beside out and moved in
    once whole, so a failure (a full disk, Ctrl-C) leaves out as it was. Returns {gaussians, sh_degree, format,
    capture}."""
    from nerfkit.training.trainer import Trainer

    file, out = Path(file), Path(out)
    g, degree, fmt = read_gaussians(file)  # a bad file is refused before anything is written
    if data is not None and not Path(data).is_dir():
        raise ConfigError(f"--data {data}: no such folder; pass the capture the splat file was made from")
    refuse_unfit_run_folder(out)
    old, own = run_files(out), data is None
    clear = bool(old)
    if clear and not overwrite:  # not train's message: import has no --resume
        raise ConfigError(f"--out {out}: already holds a run; pass --overwrite to replace it, or pick a new --out")
    inside = [p for p in old if file.resolve().is_relative_to(p.resolve())]
    if inside and overwrite:
        raise ConfigError(f"{file}: lies in {inside[0]}, which --overwrite removes with the earlier run in {out}; "
                          f"copy the file elsewhere first, or pick another --out")
    if own and (out / "capture").exists() and not overwrite:
        raise ConfigError(f"--out {out}: already holds capture/, which the import writes its renders into; pass "
                          f"--overwrite to replace it, or pick a new --out")
    cfg = preset("splat")
    cfg.splat.capacity, cfg.splat.sh_degree, cfg.splat.init = len(g["means"]), degree, str(file.resolve())
    cfg.train.max_steps = 0
    if own:  # renders: one exposure, exact poses
        cfg.splat.appearance, cfg.train.pose_refine = "off", "off"
    with staged_folder(out) as tmp:  # a disk that fills half way leaves out as it was (no half-made run)
        if own:
            data = write_orbit_capture(g, degree, tmp / "capture")
        Trainer(data, tmp, cfg, progress=False).run()
        if clear:  # only now: a failure above leaves the earlier run as it was
            clear_run(out)
        if own:
            data = _moved_capture(tmp, out)
            shutil.rmtree(out / "capture", ignore_errors=True)
    if own:
        log(f"import: no capture given; {data} holds {ORBIT_VIEWS} renders of the file on an orbit around it")
    log(f"import: {len(g['means']):,} Gaussians of {file.name} ({fmt.name}, SH degree {degree}), in the frame of "
        f"{data}")
    return {"gaussians": len(g["means"]), "sh_degree": degree, "format": fmt.name, "capture": str(data)}


def _moved_capture(tmp: Path, out: Path) -> Path:
    """Point tmp/scene.json, a run made in staging folder tmp around its own capture tmp/capture, at out/capture,
    where the capture will be once tmp's files are moved into out. Returns out/capture."""
    scene_file = tmp / "scene.json"
    scene = json.loads(scene_file.read_text())
    capture = out.parent.resolve() / out.name / "capture"
    assert Path(scene["data_dir"]) == (tmp / "capture").resolve(), scene["data_dir"]
    scene["data_dir"] = str(capture)
    scene_file.write_text(json.dumps(scene, indent=2))
    return capture
