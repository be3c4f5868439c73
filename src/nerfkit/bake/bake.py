"""`nerfkit bake`: distil a trained fast field into the baked format (format.py).

For each brick of BRICK^3 cells that touches an occupied cell of the run's occupancy grid,
the field is sampled at the brick's (BRICK + 1)^3 cell vertices: the log-density log sigma(x),
and the colour c(x, d_j) along D fixed directions d_j (a Fibonacci sphere). The view-dependent
colour is fitted, per vertex and channel, by least squares in the real SH basis Y of
sh_bands bands:

    coeff = argmin_a sum_j (Y(d_j) . a - c(x, d_j))^2 = pinv(Y) c,     Y: [D, SH]

(the PlenOctrees design: no network at render time). Bricks whose density never reaches the
field's occupancy threshold are dropped. finetune.py then optimises the baked values against
the training images through the reference renderer, and the coefficients are quantised.
"""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from nerfkit.bake.finetune import finetune, training_poses
from nerfkit.bake.web import write_web
from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.outputs import staged_folder
from nerfkit.encoding.sh import sh_encode
from nerfkit.models.baked.format import (
    BRICK,
    FORMAT,
    LOG_SIGMA_MIN,
    Baked,
    check_out,
    quantise,
    save_baked,
)
from nerfkit.run.folder import RunFolder
from nerfkit.sampling import occupancy

N_DIRECTIONS = 32
AUTO_RESOLUTIONS = (256, 224, 192, 160, 128, 96, 64)
BRICKS_PER_CALL = 16


def fibonacci_directions(n: int) -> np.ndarray:
    """n unit vectors [n, 3] spread evenly over the sphere (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1).astype(np.float32)


def brick_vertices(bricks: np.ndarray, bound: float, resolution: int) -> np.ndarray:
    """World positions [K, S, S, S, 3] of the cell vertices of bricks [K, 3] (S = BRICK + 1)."""
    h = 2.0 * bound / resolution
    local = np.arange(BRICK + 1)
    g = np.stack(np.meshgrid(local, local, local, indexing="ij"), -1)  # [S, S, S, 3]
    return (-bound + (bricks[:, None, None, None, :] * BRICK + g[None]) * h).astype(np.float32)


def occupied_bricks(run, resolution: int) -> np.ndarray:
    """Integer coordinates [K, 3] of the bricks that contain a point of an occupied cell (each brick's
    vertices and cell centres are tested against the run's occupancy grid)."""
    model, aux = run.model, run.aux
    m = resolution // BRICK
    allb = np.stack(np.meshgrid(*[np.arange(m)] * 3, indexing="ij"), -1).reshape(-1, 3)
    h = 2.0 * run.bound / resolution
    q = jax.jit(lambda x: occupancy.query_occupancy(aux, model.field.to_grid(x), model.occ))
    keep = np.zeros(len(allb), bool)
    for s in range(0, len(allb), 512):
        b = allb[s:s + 512]
        pts = brick_vertices(b, run.bound, resolution)
        centres = pts[:, :-1, :-1, :-1] + 0.5 * h
        x = np.concatenate([pts.reshape(len(b), -1, 3), centres.reshape(len(b), -1, 3)], 1)
        keep[s:s + 512] = np.asarray(q(jnp.asarray(x.reshape(-1, 3)))).reshape(len(b), -1).any(1)
    return allb[keep]


def start_view(poses: np.ndarray) -> dict:
    """Where the page's orbit starts, from the training poses c2w [N, 4, 4]: "up", the mean of the
    cameras' up axes (unit), and "eye", the first training camera's position."""
    up = poses[:, :3, 1].mean(0)
    return {"up": (up / max(np.linalg.norm(up), 1e-9)).tolist(), "eye": poses[0, :3, 3].tolist()}


def baked_mb(n_bricks: int, resolution: int, sh_bands: int) -> float:
    """Size in MB of a bake with n_bricks bricks: int32 index, float16 density, uint8 coefficients."""
    return ((resolution // BRICK) ** 3 * 4 + n_bricks * (BRICK + 1) ** 3 * (2 + 3 * sh_bands**2)) / 2**20


def choose_grid(run, resolution: int | None, sh_bands: int, max_mb: float, log=print):
    """(resolution, occupied bricks [K, 3]): the one asked for, or by default the finest of AUTO_RESOLUTIONS
    whose occupied bricks fit max_mb (an upper bound: bricks the field leaves empty are dropped later)."""
    for r in [resolution] if resolution is not None else AUTO_RESOLUTIONS:
        bricks = occupied_bricks(run, r)
        if not len(bricks):
            raise NerfkitError(f"{run.run_dir}: the occupancy grid is empty; nothing to bake (train longer)")
        if resolution is not None or baked_mb(len(bricks), r, sh_bands) <= max_mb:
            if r != AUTO_RESOLUTIONS[0] and resolution is None:
                log(f"resolution {r}: the finest grid whose occupied bricks fit --max-mb {max_mb:g}")
            return r, bricks
    raise NerfkitError(f"{run.run_dir}: even a {AUTO_RESOLUTIONS[-1]}^3 bake would exceed --max-mb {max_mb:g}; "
                       f"raise --max-mb or lower --sh-bands")


def sample_field(run, bricks: np.ndarray, resolution: int, sh_bands: int, progress: bool = True):
    """The field at the cell vertices of bricks [K, 3]: (bricks int [K', 3], log sigma [K', S, S, S],
    SH coefficients [K', S, S, S, 3 * sh_bands^2]) as float32 arrays, bricks below the occupancy
    threshold everywhere dropped."""
    model, p = run.model, run.params["field"]
    dirs = jnp.asarray(fibonacci_directions(N_DIRECTIONS))
    pinv = jnp.asarray(np.linalg.pinv(np.asarray(sh_encode(dirs, sh_bands))))  # [SH, D]
    emb = model.field.embedding(p, None)
    # An anti-aliased field is sampled with the footprint of one baked cell (a pixel of the cell's width).
    footprint = 2.0 * run.bound / resolution / np.sqrt(12.0) if run.cfg.field.antialias else None

    @jax.jit
    def sample(x):  # [P, 3] -> sigma [P], coefficients [P, 3 * SH]
        fp = None if footprint is None else jnp.full(x.shape[0], footprint, jnp.float32)

        def colour(d):
            return model.field(p, x, jnp.broadcast_to(d, x.shape), emb, footprint=fp)[0]  # [P, 3]

        rgb = jax.lax.map(colour, dirs)  # [D, P, 3]
        coeff = jnp.einsum("kd,dpc->pck", pinv, rgb)
        a = jnp.log(jnp.maximum(model.field.density(p, x, fp), np.exp(LOG_SIGMA_MIN)))
        return a, coeff.reshape(x.shape[0], -1)

    s = BRICK + 1
    dens, sh = [], []
    for i in tqdm(range(0, len(bricks), BRICKS_PER_CALL), desc="bake", unit="call", disable=not progress):
        b = bricks[i:i + BRICKS_PER_CALL]
        x = brick_vertices(b, run.bound, resolution).reshape(-1, 3)
        pad = BRICKS_PER_CALL * s**3 - len(x)
        sig, co = sample(jnp.asarray(np.concatenate([x, np.zeros((pad, 3), np.float32)])))
        dens.append(np.asarray(sig)[:len(x)].reshape(len(b), s, s, s))
        sh.append(np.asarray(co)[:len(x)].reshape(len(b), s, s, s, -1))
    dens, sh = np.concatenate(dens), np.concatenate(sh)
    alive = dens.reshape(len(bricks), -1).max(1) >= np.log(model.occ.threshold)
    return bricks[alive], dens[alive], sh[alive]


def bake_run(run_dir: Path, out: Path, resolution: int | None = None, sh_bands: int = 2,
             finetune_minutes: float = 0.0, max_mb: float = 50.0, progress: bool = True, log=print,
             finetune_steps: int | None = None, overwrite: bool = False) -> dict:
    """Bake a fast-field run into `out` (format.py); returns its summary (bricks, size, seconds).
    resolution None: the finest of AUTO_RESOLUTIONS that fits max_mb. finetune_steps: fine-tune for
    that many steps instead of finetune_minutes (tests)."""
    if resolution is not None and (resolution % BRICK or not 2 * BRICK <= resolution <= 1024):
        raise ConfigError(f"--resolution must be a multiple of {BRICK} between {2 * BRICK} and 1024 (got {resolution})")
    if not 1 <= sh_bands <= 3:
        raise ConfigError(f"--sh-bands must be 1, 2 or 3 (got {sh_bands})")
    if not 0 <= finetune_minutes < 1e6:  # also refuses NaN
        raise ConfigError(f"--finetune-minutes must be a number of minutes >= 0 (got {finetune_minutes})")
    check_out(out, overwrite)
    t0 = time.perf_counter()
    run = RunFolder(run_dir).load()
    if not run.model.supports.bake or run.model.unbounded:
        raise ConfigError(f"{run_dir}: bake needs a bounded fast-field run (ngp preset on a Blender scene or a "
                          f"masked capture); this one is {run.model.title}, {run.cfg.field.scene_type}")
    poses = training_poses(run)  # reads the capture: a missing data folder fails here, before any work
    resolution, bricks = choose_grid(run, resolution, sh_bands, max_mb, log)
    bricks, dens, sh = sample_field(run, bricks, resolution, sh_bands, progress)
    if not len(bricks):
        raise NerfkitError(f"{run_dir}: no baked brick reaches the occupancy threshold; nothing to bake (train longer)")
    m = resolution // BRICK
    index = np.full((m, m, m), -1, np.int32)
    index[bricks[:, 0], bricks[:, 1], bricks[:, 2]] = np.arange(len(bricks), dtype=np.int32)
    mb = baked_mb(len(bricks), resolution, sh_bands)
    if mb > max_mb:
        raise NerfkitError(f"the bake would take {mb:.1f} MB, over --max-mb {max_mb:g}; lower --resolution or "
                           f"--sh-bands, or raise --max-mb")
    model = run.model
    meta = {"format": FORMAT, "bound": run.bound, "resolution": resolution, "brick": BRICK, "sh_bands": sh_bands,
            "step": min(model.step_size, run.bound / resolution), "near": float(model.near),
            "far": float(model.far), "background": run.cfg.data.background, "transform": run.transform.tolist(),
            "run": str(Path(run_dir).resolve()), "step_trained": run.step, "bricks": int(len(bricks))}
    meta.update(start_view(poses))
    if finetune_minutes > 0 or finetune_steps:
        dens, sh, tuned = finetune(run, Baked(meta, index, dens, sh), finetune_minutes, progress, log, finetune_steps)
        meta["finetune"] = tuned
    q, meta["sh_range"] = quantise(sh)
    baked = Baked(meta, index, dens.astype(np.float16), q)
    with staged_folder(out) as tmp:  # a disk that fills half way leaves out as it was (an earlier bake whole)
        save_baked(tmp, baked)
        write_web(tmp)
    seconds = time.perf_counter() - t0
    log(f"baked {len(bricks)} bricks of {BRICK}^3 cells ({len(bricks) / m**3:.1%} of the {resolution}^3 grid) into "
        f"{out}: {mb:.1f} MB, {seconds:.0f} s")
    return {"bricks": int(len(bricks)), "resolution": resolution, "mb": mb, "seconds": seconds, "out": str(out)}
