"""Splat files, by extension: the formats `nerfkit export splat` writes and `nerfkit import splat` reads
(.ply, .spz, .splat, .glb / .gltf, .sog).

Adding a format is a module defining FORMAT (a `SplatFormat`, below) and one line in FORMATS. The
exporter (export/splat.py), the importer (run/imported.py) and their help read this table.

Every format module speaks the same Gaussians: gaussians.py's parameters as numpy arrays

    means [N, 3]   log_scales [N, 3]   quats [N, 4] (w, x, y, z)   opacity [N] (logit)
    sh_dc [N, 1, 3]   sh_rest [N, 15, 3] (bands 1..3; zeros past the file's degree)

in the capture's own coordinates (the frame of its COLMAP model or poses: x right, y down, z forward
for a camera, the convention of the Inria .ply). A format whose own convention differs (SPZ's RUB
axes, glTF's +Y up) converts inside its module, both ways.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from nerfkit.core.errors import ConfigError

FORMATS: dict[str, str] = {  # extension -> the module that defines its FORMAT (imported when used)
    ".ply": "nerfkit.models.splat.formats.ply",
    ".spz": "nerfkit.models.splat.formats.spz",
    ".splat": "nerfkit.models.splat.formats.antimatter",
    ".glb": "nerfkit.models.splat.formats.gltf",
    ".gltf": "nerfkit.models.splat.formats.gltf",
    ".sog": "nerfkit.models.splat.formats.sog",
}

N_REST = 15  # SH coefficients of bands 1..3
REST_OF_DEGREE = (0, 3, 8, 15)  # SH coefficients of bands 1..d, per channel, for SH degree d = 0..3
SH_C0 = 0.28209479177387814  # project.py's; repeated so that the format modules stay numpy-only
RDF_TO_RUB = np.diag([1.0, -1.0, -1.0, 1.0])  # capture axes -> SPZ and glTF axes (180 degrees about x); self-inverse


def unit_quats(q: np.ndarray) -> np.ndarray:
    """q / |q| [N, 4], in q's dtype (zero quaternions stay zero: check_gaussians refuses them on reading)."""
    return q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)


def base_colour(sh_dc: np.ndarray) -> np.ndarray:
    """The degree-0 colour clip(SH_C0 sh_dc + 0.5, 0, 1) [N, 3] (float64) of sh_dc [N, 1, 3] or [N, 3]."""
    return np.clip(SH_C0 * np.asarray(sh_dc, np.float64).reshape(-1, 3) + 0.5, 0.0, 1.0)


@dataclass(frozen=True)
class SplatFormat:
    """One splat file format.

    name      what the file is, in words ("Inria 3DGS .ply")
    opens     the programs that open it, in words (for the docs, the help and the export record)
    max_sh    the highest SH degree the file keeps (0: view-independent colour only)
    write     (path, gaussians, sh_degree) -> None: write the Gaussians (capture coordinates) to path
    read      path -> (gaussians, sh_degree), or None where nerfkit does not read the format
    """

    name: str
    opens: str
    max_sh: int
    write: Callable[[Path, dict, int], None]
    read: Callable[[Path], tuple[dict, int]] | None = None


def from_gsply(d) -> tuple[dict, int]:
    """(Gaussians in the layout above, SH degree) of a gsply GSData d as its readers return it (means, log scales,
    w-first quaternions, logit opacities, sh0 [N, 3], shN [N, K, 3] or None), in the file's own axes;
    ValueError unless K is 0, 3, 8 or 15."""
    n = len(d.means)
    k = 0 if d.shN is None else int(np.asarray(d.shN).shape[1])
    if k not in REST_OF_DEGREE:
        raise ValueError(f"{k} higher SH coefficients per channel (expected 0, 3, 8 or 15)")
    rest = np.zeros((n, N_REST, 3), np.float32)
    if k:
        rest[:, :k] = np.asarray(d.shN, np.float32).reshape(n, k, 3)
    g = {"means": np.asarray(d.means, np.float32), "log_scales": np.asarray(d.scales, np.float32),
         "quats": np.asarray(d.quats, np.float32), "opacity": np.asarray(d.opacities, np.float32).reshape(n),
         "sh_dc": np.asarray(d.sh0, np.float32).reshape(n, 1, 3), "sh_rest": rest}
    return g, REST_OF_DEGREE.index(k)


def splat_format(path: str | Path, flag: str = "--out") -> SplatFormat:
    """The format of `path`, by its extension; ConfigError naming the extensions there are otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ConfigError(f"{f'{flag} ' if flag else ''}{path}: no splat format has the extension "
                          f"{suffix or '(none)'!r}; use " + ", ".join(FORMATS))
    return importlib.import_module(FORMATS[suffix]).FORMAT


def readable() -> list[str]:
    """The extensions nerfkit reads splats from."""
    return [s for s, module in FORMATS.items() if importlib.import_module(module).FORMAT.read is not None]


def check_gaussians(g: dict, n_min: int = 1) -> None:
    """ValueError saying what is wrong unless `g` holds n >= n_min Gaussians of consistent shapes, all finite,
    with non-zero quaternions."""
    n = len(g["means"])
    if n < n_min:
        raise ValueError(f"{n} Gaussians (at least {n_min} needed)")
    shapes = {"means": (n, 3), "log_scales": (n, 3), "quats": (n, 4), "opacity": (n,), "sh_dc": (n, 1, 3),
              "sh_rest": (n, N_REST, 3)}
    for key, shape in shapes.items():
        if g[key].shape != shape:
            raise ValueError(f"{key} has shape {g[key].shape}, expected {shape}")
        bad = ~np.isfinite(g[key])
        if bad.any():
            row = int(np.argwhere(bad.reshape(n, -1).any(axis=1))[0, 0])
            raise ValueError(f"{int(bad.reshape(n, -1).any(axis=1).sum())} Gaussians hold NaN or infinite {key} "
                             f"(the first: number {row})")
    zero = np.linalg.norm(g["quats"], axis=1) == 0
    if zero.any():
        raise ValueError(f"{int(zero.sum())} Gaussians have a zero rotation quaternion (the first: number "
                         f"{int(np.argmax(zero))})")


def read_gaussians(path: str | Path, flag: str = "") -> tuple[dict, int, SplatFormat]:
    """(Gaussians, SH degree, format) of a splat file, checked (check_gaussians); ConfigError with one line
    naming the file and what is wrong when it is missing, of an unknown or write-only format, truncated, of
    another layout, or holds NaNs."""
    path = Path(path)
    fmt = splat_format(path, flag)
    if fmt.read is None:
        raise ConfigError(f"{path}: nerfkit writes {fmt.name} files but does not read them; read a "
                          + " or ".join(readable()))
    if not path.is_file():
        raise ConfigError(f"{path}: no such file; pass a splat file ({', '.join(readable())})")
    try:
        g, degree = fmt.read(path)
        g = {k: np.asarray(v, np.float32) for k, v in g.items()}
        check_gaussians(g)
    except Exception as e:  # noqa: BLE001 - a file parser's every failure is the file's fault, said in one line
        raise ConfigError(f"{path}: not a usable {fmt.name} file: {_reason(e)}") from None
    return g, degree, fmt


def _reason(e: Exception) -> str:
    text = " ".join(str(e).split()) or "no detail"
    return text if isinstance(e, ValueError) else f"{type(e).__name__}: {text}"
