"""`nerfkit bake` of a splat run: a self-contained static page (WebGL2) that sorts and draws the Gaussians.

The folder holds index.html and splat.js (web/, no build step, no network beyond the folder),
splats.json (format, count, SH degree, background, the first training camera and pose) and
splats.bin: N x 64 float32 (little-endian), per Gaussian

    [0:3] mean, [3] opacity (sigmoid applied), [4:10] the 3D covariance's upper triangle
    (xx, xy, xz, yy, yz, zz), [10:12] zero, [12:60] the 16 SH coefficients x RGB (coefficient k,
    channel c at 12 + 3k + c; bands above the run's degree are zero), [60:64] zero,

i.e. 16 RGBA32F texels, which the page uploads as one texture (see web/splat.js for the drawing).
The Gaussians stay in the run's normalised frame, like the cameras the page starts from.
`nerfkit view --baked DIR` serves the folder (bake/web.py).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.core.outputs import staged_folder
from nerfkit.export.splat import active_gaussians
from nerfkit.models.splat.project import covariance_3d
from nerfkit.run.folder import RunFolder

FORMAT = "nerfkit-splats-v1"
WEB_DIR = Path(__file__).parent / "web" / "splat"
ASSETS = ("index.html", "splat.js")
FLOATS = 64


def pack_gaussians(params: dict, sh_degree: int) -> np.ndarray:
    """[N, 64] float32 rows of the layout above, from gaussians.py's parameters (numpy)."""
    n = len(params["means"])
    cov = np.asarray(covariance_3d(jnp.asarray(params["log_scales"]), jnp.asarray(params["quats"])), np.float64)
    sh = np.concatenate([params["sh_dc"], params["sh_rest"]], axis=1).astype(np.float32)  # [N, 16, 3]
    sh[:, (sh_degree + 1) ** 2:] = 0.0
    out = np.zeros((n, FLOATS), np.float32)
    out[:, 0:3] = params["means"]
    out[:, 3] = 1.0 / (1.0 + np.exp(-np.asarray(params["opacity"], np.float64)))
    out[:, 4:10] = cov[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    out[:, 12:60] = sh.reshape(n, 48)
    return out


def check_out(out: Path, overwrite: bool = False) -> None:
    """`out` must be a new or empty folder, or (with `overwrite`) hold a baked splat page, which is replaced."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: is a file; give a folder for the baked page")
    if out.is_dir() and any(out.iterdir()):
        if not (out / "splats.json").exists():
            raise ConfigError(f"--out {out}: folder is not empty and holds no baked splats; pick a new or empty folder")
        if not overwrite:
            raise ConfigError(f"--out {out}: holds baked splats; pass --overwrite to replace them, or pick a new "
                              f"folder")


def write_splat_page(run_dir: Path, out: Path, overwrite: bool = False, log=print) -> dict:
    """Write the page of a splat run into the folder `out` (checked first: check_out), all its files or none
    (core/outputs.staged_folder). Returns the content of its splats.json."""
    check_out(out, overwrite)
    run = RunFolder(run_dir).load()
    g = active_gaussians(run)
    degree = run.cfg.splat.sh_degree
    packed = pack_gaussians(g, degree)
    meta = {"format": FORMAT, "count": int(len(packed)), "sh_degree": degree,
            "dilation": run.cfg.splat.screen_dilation,
            "background": list(run.model.background), "camera": run.scene["camera"],
            "pose": run.scene["train_poses"][0], "run": str(Path(run_dir).resolve()), "step": run.step,
            "frame": "the run's normalised frame (scene.json transform)"}
    with staged_folder(Path(out)) as tmp:  # a disk that fills half way leaves out as it was (an earlier bake whole)
        packed.astype("<f4").tofile(tmp / "splats.bin")
        for name in ASSETS:
            shutil.copyfile(WEB_DIR / name, tmp / name)
        (tmp / "splats.json").write_text(json.dumps(meta, indent=2))
    log(f"baked {len(packed)} Gaussians (SH degree {degree}) into {out}: index.html, splat.js, splats.json, "
        f"splats.bin ({packed.nbytes / 2**20:.1f} MB)")
    return meta
