"""The baked scene format (nerfkit-baked-v0) and its look-up: the specification a renderer must follow.

A baked scene samples a trained field on the vertices of an N^3 grid of cells over the box
[-B, B]^3 (cell size h = 2B / N), stored only in occupied bricks of BRICK^3 cells:

    DIR/baked.json     {"format", "bound" B, "resolution" N, "brick", "sh_bands", "step", "near", "far",
                        "background", "transform", ...}
    DIR/index.npy      int32 [M, M, M], M = N / BRICK: brick id of each brick of cells, -1 when empty
    DIR/density.npy    float16 [K, S, S, S], S = BRICK + 1: sigma at the brick's cell vertices
    DIR/sh.npy         float16 [K, S, S, S, 3 * SH], SH = sh_bands^2: colour coefficients (r's, g's, b's)

A point x lies in cell c = floor((x + B) / h) (clamped to [0, N-1]) of brick c // BRICK at
local cell c % BRICK; its values are the trilinear interpolation of that cell's 8 vertices
(each brick holds its own boundary vertices, so interpolation never crosses bricks). Empty
bricks and points outside the box have sigma = 0. The colour seen along unit direction d is

    rgb = clip(sum_k coeff[c, k] Y_k(d), 0, 1)        (Y: encoding/sh.py, bands 0..sh_bands-1)

Rays march like the fast field's (model.py / occupancy.box_candidates) with t-step "step",
skipping empty bricks, and composite with w_i = T_i (1 - exp(-sigma_i delta_i)).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from nerfkit.errors import ConfigError

FORMAT = "nerfkit-baked-v0"
BRICK = 8
SH_BANDS = 3


@dataclass
class Baked:
    meta: dict
    index: np.ndarray  # int32 [M, M, M]
    density: np.ndarray  # float16 [K, S, S, S]
    sh: np.ndarray  # float16 [K, S, S, S, 3 * SH]

    @property
    def bound(self) -> float:
        return float(self.meta["bound"])

    @property
    def resolution(self) -> int:
        return int(self.meta["resolution"])

    def nbytes(self) -> int:
        return int(self.index.nbytes + self.density.nbytes + self.sh.nbytes)

    def arrays(self) -> dict:
        """Device arrays for `lookup` (float32)."""
        return {"index": jnp.asarray(self.index), "density": jnp.asarray(self.density, jnp.float32),
                "sh": jnp.asarray(self.sh, jnp.float32)}


def save_baked(out: Path, baked: Baked) -> None:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name in ("index", "density", "sh"):
        np.save(out / f"{name}.npy", getattr(baked, name), allow_pickle=False)
    (out / "baked.json").write_text(json.dumps(baked.meta, indent=2))


def load_baked(path: Path) -> Baked:
    path = Path(path)
    try:
        meta = json.loads((path / "baked.json").read_text())
    except (OSError, ValueError):
        raise ConfigError(f"{path}: not a baked scene (no readable baked.json); make one with nerfkit bake RUN --out "
                          f"{path}") from None
    if meta.get("format") != FORMAT:
        raise ConfigError(f"{path / 'baked.json'}: format {meta.get('format')!r}, expected {FORMAT!r}; bake it again")
    try:
        arrays = {n: np.load(path / f"{n}.npy", allow_pickle=False) for n in ("index", "density", "sh")}
    except (OSError, ValueError) as e:
        raise ConfigError(f"{path}: a baked array is missing or unreadable ({e}); bake it again") from None
    return Baked(meta, arrays["index"], arrays["density"], arrays["sh"])


def lookup(arrays: dict, x: jnp.ndarray, bound: float, resolution: int):
    """(sigma [P], coefficients [P, 3 * SH]) at points x [P, 3] (see the module docstring)."""
    n = resolution
    h = 2.0 * bound / n
    u = (x + bound) / h
    inside = jnp.all((u >= 0) & (u <= n), axis=-1)
    cell = jnp.clip(jnp.floor(u), 0, n - 1).astype(jnp.int32)
    f = jnp.clip(u - cell, 0.0, 1.0)
    b = cell // BRICK
    local = cell % BRICK
    bid = arrays["index"][b[:, 0], b[:, 1], b[:, 2]]
    valid = inside & (bid >= 0)
    k = jnp.maximum(bid, 0)
    sigma = jnp.zeros(x.shape[0], jnp.float32)
    coeff = jnp.zeros((x.shape[0], arrays["sh"].shape[-1]), jnp.float32)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = ((f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1])
                     * (f[:, 2] if dz else 1 - f[:, 2]))
                i, j, l_ = local[:, 0] + dx, local[:, 1] + dy, local[:, 2] + dz
                sigma = sigma + w * arrays["density"][k, i, j, l_]
                coeff = coeff + w[:, None] * arrays["sh"][k, i, j, l_]
    return jnp.where(valid, jnp.maximum(sigma, 0.0), 0.0), coeff
