"""The baked scene format (nerfkit-baked-v1) and its look-up: the specification a renderer must follow.

A baked scene samples a trained field on the vertices of an N^3 grid of cells over the box
[-B, B]^3 (cell size h = 2B / N), stored only in occupied bricks of BRICK^3 cells:

    DIR/baked.json     {"format", "bound" B, "resolution" N, "brick", "sh_bands", "sh_range",
                        "step", "near", "far", "background", "transform", ...}
    DIR/index.npy      int32 [M, M, M], M = N / BRICK: brick id of each brick of cells, -1 when empty
    DIR/density.npy    float16 [K, S, S, S], S = BRICK + 1: log-density a = log sigma at the
                       brick's cell vertices (at least LOG_SIGMA_MIN)
    DIR/sh.npy         uint8 [K, S, S, S, C], C = 3 * sh_bands^2: colour coefficients, quantised
                       per channel j to [lo_j, hi_j] = sh_range[j] (channels: r's, then g's, b's)

A point x lies in cell c = floor((x + B) / h) (clamped to [0, N-1]) of brick c // BRICK at
local cell c % BRICK, with fraction f = (x + B) / h - c. Its values are the trilinear
interpolation of that cell's 8 vertices (each brick holds its own boundary vertices, so
interpolation never crosses bricks; this is what a GPU's filtered 3D texture look-up does):

    sigma  = exp(trilinear(a))                       (the activation after interpolation, as in
                                                      SNeRG and MERF: surfaces stay sharp)
    coeff  = lo + (hi - lo) * trilinear(q) / 255     (affine, so it commutes with interpolation)
    rgb(d) = clip(sum_k coeff[c, k] Y_k(d), 0, 1)    (Y: encoding/sh.py, bands 0..sh_bands-1)

Empty bricks and points outside the box have sigma = 0. A ray o + t d (|d| need not be 1)
marches from t_lo = max(near, box entry) to t_hi = min(far, box exit) at t-step "step":
interval k is [t_lo + k step, min(t_lo + (k+1) step, t_hi)] (k = 0, 1, ... while it starts
before t_hi), its sample sits at the interval's midpoint, delta_k = its length times |d|, and
the samples composite as

    w_k = T_k (1 - exp(-sigma_k delta_k)),  T_k = prod_{j<k} exp(-sigma_j delta_j),
    rgb = sum_k w_k rgb_k + (1 - sum_k w_k) background,

stopping once T_k < 1e-4 (model.py; index.html's shader does the same).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.core.outputs import replace_with

FORMAT = "nerfkit-baked-v1"
BRICK = 8
LOG_SIGMA_MIN = -12.0


@dataclass
class Baked:
    meta: dict
    index: np.ndarray  # int32 [M, M, M]
    density: np.ndarray  # float16 [K, S, S, S], log sigma
    sh: np.ndarray  # uint8 [K, S, S, S, C]

    @property
    def bound(self) -> float:
        return float(self.meta["bound"])

    @property
    def resolution(self) -> int:
        return int(self.meta["resolution"])

    def nbytes(self) -> int:
        return int(self.index.nbytes + self.density.nbytes + self.sh.nbytes)

    def sh_float(self) -> np.ndarray:
        """Dequantised coefficients [K, S, S, S, C] (float32)."""
        lo, hi = np.asarray(self.meta["sh_range"], np.float32).T
        return lo + (hi - lo) * (self.sh.astype(np.float32) / 255.0)

    def arrays(self) -> dict:
        """Device arrays for `lookup` (float32, dequantised: interpolation commutes with the affine map)."""
        return {"index": jnp.asarray(self.index), "density": jnp.asarray(self.density, jnp.float32),
                "sh": jnp.asarray(self.sh_float())}


def quantise(coeff: np.ndarray) -> tuple[np.ndarray, list]:
    """uint8 codes of float coefficients [..., C] and the per-channel ranges [[lo, hi]] * C."""
    flat = coeff.reshape(-1, coeff.shape[-1])
    lo, hi = flat.min(0), flat.max(0)
    hi = np.maximum(hi, lo + 1e-6)
    q = np.clip(np.rint((coeff - lo) / (hi - lo) * 255.0), 0, 255).astype(np.uint8)
    return q, np.stack([lo, hi], 1).astype(float).tolist()


def check_out(out: Path, overwrite: bool = False) -> None:
    """`out` must be a new or empty folder, or (with `overwrite`) hold a baked scene, which is replaced."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: is a file; give a folder for the baked scene")
    if out.is_dir() and any(out.iterdir()):
        if not (out / "baked.json").exists():
            raise ConfigError(f"--out {out}: folder is not empty and holds no baked scene; pick a new or empty folder")
        if not overwrite:
            raise ConfigError(f"--out {out}: holds a baked scene; pass --overwrite to replace it, or pick a new folder")


def save_baked(out: Path, baked: Baked) -> None:
    """Write the arrays, then baked.json last (a folder without it is not a baked scene, so an
    interrupted write is never mistaken for a complete one)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "baked.json").unlink(missing_ok=True)
    for name in ("index", "density", "sh"):
        np.save(out / f"{name}.npy", getattr(baked, name), allow_pickle=False)
    replace_with(out / "baked.json", lambda tmp: tmp.write_text(json.dumps(baked.meta, indent=2)))


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
    """(sigma [P], coefficients [P, C]) at points x [P, 3] (see the module docstring); arrays holds
    index [M, M, M], density [K, S, S, S] (log sigma) and sh [K, S, S, S, C] (dequantised)."""
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
    a = jnp.zeros(x.shape[0], jnp.float32)
    coeff = jnp.zeros((x.shape[0], arrays["sh"].shape[-1]), jnp.float32)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = ((f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1])
                     * (f[:, 2] if dz else 1 - f[:, 2]))
                i, j, l_ = local[:, 0] + dx, local[:, 1] + dy, local[:, 2] + dz
                a = a + w * arrays["density"][k, i, j, l_]
                coeff = coeff + w[:, None] * arrays["sh"][k, i, j, l_]
    return jnp.where(valid, jnp.exp(jnp.minimum(a, 15.0)), 0.0), coeff
