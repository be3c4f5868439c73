"""Gaussians to and from PlayCanvas's .sog (SOG version 2, "Spatially Ordered Gaussians": what SuperSplat, the
PlayCanvas engine and Spark open). Written here (numpy, scipy's k-means, Pillow's lossless WebP); read through
gsply (its SOG reader, with imagecodecs' WebP decoder).

A .sog is a zip of meta.json and lossless WebP images, one pixel per Gaussian at the same place in every image
(row-major, W = 4 ceil(sqrt(N) / 4) wide), the Gaussians in the Morton order of their positions (spatially
ordered: neighbours in the image are neighbours in space, which is what the WebP compresses). Per Gaussian
(developer.playcanvas.com, user-manual/gaussian-splatting/formats/sog):

    means      n = sign(x) ln(1 + |x|) per axis, 16 bits over [min n, max n] (meta), low and high bytes in two
               images (means_l, means_u)
    quats      the unit quaternion (w, x, y, z) with its largest component made positive and left out: the other
               three as round(255 (sqrt2 q_i / 2 + 1 / 2)), alpha 252 + the index of the one left out
    scales     each log scale an 8-bit index into a 256-entry codebook (meta; 1-D k-means of all three axes)
    sh0        each f_dc channel an index into a codebook of its own the same way; alpha round(255 sigmoid(o))
    shN        (SH degree d >= 1) each Gaussian's bands 1..d replaced by the nearest entry of a palette of P
               (k-means in 3 K dimensions, K = 3, 8 or 15 coefficients), its 16-bit label in shN_labels; the
               palette's coefficients as indices into a 256-entry codebook, entry n's coefficient c at pixel
               ((n % 64) K + c, n // 64) of shN_centroids (r, g, b: its three channels)

Axes: the capture's, as stored in the Inria .ply (PlayCanvas's splat-transform writes a .ply's Gaussians to SOG
without turning them), so a .sog and the .ply of the same run load alike in PlayCanvas.

Palette: PlayCanvas's tool clusters min(64, 2^floor(log2(N / 1024))) x 1024 entries on a GPU (32,768 for 50k
Gaussians); scipy's k-means on 2 CPU cores takes seconds per thousand entries, so here P = min(N, PALETTE) (N or
fewer: every Gaussian's own bands, only the codebook rounds them); the measured cost is on the export page.
"""

from __future__ import annotations

import io
import json
import math
import warnings
import zipfile
from pathlib import Path

import numpy as np

from nerfkit.models.splat.formats import REST_OF_DEGREE, SplatFormat, from_gsply, unit_quats

SOG_VERSION = 2
CODEBOOK = 256  # entries of each 1-D codebook (an 8-bit index)
PALETTE = 4096  # SH palette entries at most (shN)
KMEANS_ITER = 10
MORTON_BITS = 10  # per axis, for the spatial order
_IMAGES = ("means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp")
_SH_IMAGES = ("shN_centroids.webp", "shN_labels.webp")


def _log_transform(x: np.ndarray) -> np.ndarray:
    """n = sign(x) ln(1 + |x|) (SOG's positions, elementwise)."""
    return np.sign(x) * np.log1p(np.abs(x))


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """v [N] (integers < 2^10) with two zero bits after each of its bits (uint64), for a 3-D Morton code."""
    v = v.astype(np.uint64) & np.uint64(0x3FF)
    for shift, mask in ((16, 0x030000FF), (8, 0x0300F00F), (4, 0x030C30C3), (2, 0x09249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def morton_order(means: np.ndarray) -> np.ndarray:
    """Indices [N] sorting the points means [N, 3] along a Z-order curve through their bounding box (MORTON_BITS
    per axis; ties in index order)."""
    lo, hi = means.min(0), means.max(0)
    q = np.floor((means - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << MORTON_BITS) - 1) + 0.5).astype(np.int64)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << np.uint64(1)) | (_spread_bits(q[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


def codebook_1d(values: np.ndarray, size: int = CODEBOOK, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(codebook [size] float32, labels uint8 shaped as values): 1-D k-means of all of values (scipy's kmeans2,
    KMEANS_ITER rounds from the values' quantiles), each value's nearest entry. Fewer distinct values than
    entries: each its own entry. The codebook is sorted and padded to `size` with its last entry."""
    from scipy.cluster.vq import kmeans2, vq

    flat = np.asarray(values, np.float64).reshape(-1)
    distinct = np.unique(flat)
    if len(distinct) <= size:
        book = distinct
    else:
        start = np.unique(np.quantile(flat, (np.arange(size) + 0.5) / size))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty cluster keeps its entry (kmeans2's "warn")
            book, _ = kmeans2(flat, start, iter=KMEANS_ITER, minit="matrix", seed=seed)
        book = np.unique(book)
    labels, _ = vq(flat[:, None], book[:, None])
    padded = np.concatenate([book, np.full(size - len(book), book[-1])]).astype(np.float32)
    return padded, labels.astype(np.uint8).reshape(np.shape(values))


def palette_size(n: int) -> int:
    """SH palette entries for n Gaussians: min(n, PALETTE)."""
    return int(min(n, PALETTE))


def sh_palette(rest: np.ndarray, size: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(palette [P, K, 3] float64, labels [N] int) of the SH bands rest [N, K, 3] as vectors of 3 K numbers: the
    distinct vectors themselves where there are at most `size`, else their k-means (scipy's kmeans2, KMEANS_ITER
    rounds from `size` of the Gaussians drawn at random)."""
    from scipy.cluster.vq import kmeans2

    n, k = rest.shape[:2]
    flat = np.asarray(rest, np.float64).reshape(n, 3 * k)
    distinct, inverse = np.unique(flat, axis=0, return_inverse=True)
    if len(distinct) <= size:
        return distinct.reshape(-1, k, 3), inverse.reshape(-1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        book, labels = kmeans2(flat, size, iter=KMEANS_ITER, minit="points", seed=seed)
    return book.reshape(-1, k, 3), labels


def _image(columns: list[np.ndarray], order: np.ndarray, width: int, height: int, alpha=None) -> np.ndarray:
    """An RGBA uint8 image [height, width, 4]: pixel i holds columns[c][order[i]] in channel c (zeros past the
    count; alpha 255 unless given)."""
    out = np.zeros((height * width, 4), np.uint8)
    n = len(order)
    for c, col in enumerate(columns):
        out[:n, c] = np.asarray(col)[order]
    out[:n, 3] = 255 if alpha is None else np.asarray(alpha)[order]
    return out.reshape(height, width, 4)


def _webp(rgba: np.ndarray) -> bytes:
    """Lossless WebP of an RGBA uint8 image (Pillow; exact: colour kept under zero alpha too)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(buf, format="WEBP", lossless=True, quality=100, method=4, exact=True)
    return buf.getvalue()


def _quat_bytes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rgb [N, 3] uint8, alpha [N] uint8): the smallest three of unit quaternions q [N, 4] (module docstring)."""
    q = unit_quats(np.asarray(q, np.float64))
    big = np.argmax(np.abs(q), axis=1)
    q = q * np.where(q[np.arange(len(q)), big] < 0, -1.0, 1.0)[:, None]
    keep = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[big]
    three = np.take_along_axis(q, keep, axis=1) * math.sqrt(2.0)
    rgb = np.clip(np.floor(255.0 * (0.5 * three + 0.5) + 0.5), 0, 255).astype(np.uint8)
    return rgb, (252 + big).astype(np.uint8)


def write_sog(path: str | Path, g: dict, sh_degree: int = 3) -> None:
    """Write Gaussians (capture coordinates, gaussians.py's layout) to a .sog bundle with `sh_degree` bands."""
    means = np.asarray(g["means"], np.float64)
    n = len(means)
    order = morton_order(means)
    width = 4 * math.ceil(math.sqrt(n) / 4)
    height = 4 * math.ceil(n / width / 4)
    files = {}

    logm = _log_transform(means)
    lo, hi = logm.min(0), logm.max(0)
    q16 = np.floor((logm - lo) / np.where(hi > lo, hi - lo, 1.0) * 65535.0 + 0.5).astype(np.int64)
    files["means_l.webp"] = _image([q16[:, i] & 0xFF for i in range(3)], order, width, height)
    files["means_u.webp"] = _image([q16[:, i] >> 8 for i in range(3)], order, width, height)
    rgb, mode = _quat_bytes(g["quats"])
    files["quats.webp"] = _image([rgb[:, i] for i in range(3)], order, width, height, alpha=mode)
    scale_book, scale_idx = codebook_1d(np.asarray(g["log_scales"], np.float64))
    files["scales.webp"] = _image([scale_idx[:, i] for i in range(3)], order, width, height)
    dc_book, dc_idx = codebook_1d(np.asarray(g["sh_dc"], np.float64).reshape(n, 3))
    opacity = 1.0 / (1.0 + np.exp(-np.asarray(g["opacity"], np.float64).reshape(n)))
    files["sh0.webp"] = _image([dc_idx[:, i] for i in range(3)], order, width, height,
                               alpha=np.floor(255.0 * opacity + 0.5).astype(np.uint8))
    meta = {"version": SOG_VERSION, "asset": {"generator": "nerfkit"}, "count": n, "antialias": False,
            "means": {"mins": lo.tolist(), "maxs": hi.tolist(), "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"codebook": scale_book.tolist(), "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"codebook": dc_book.tolist(), "files": ["sh0.webp"]}}
    k = REST_OF_DEGREE[sh_degree]
    if k:
        palette, labels = sh_palette(np.asarray(g["sh_rest"], np.float64)[:, :k], palette_size(n))
        book, codes = codebook_1d(palette)  # codes [P, K, 3]
        rows = math.ceil(len(palette) / 64)
        cent = np.zeros((rows * 64, k, 4), np.uint8)
        cent[:len(palette), :, :3] = codes
        cent[:len(palette), :, 3] = 255
        files["shN_centroids.webp"] = cent.reshape(rows, 64 * k, 4)
        files["shN_labels.webp"] = _image([labels & 0xFF, labels >> 8], order, width, height)
        meta["shN"] = {"count": len(palette), "bands": sh_degree, "codebook": book.tolist(), "files": list(_SH_IMAGES)}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:  # WebP is compressed already
        z.writestr("meta.json", json.dumps(meta))
        for name, rgba in files.items():
            z.writestr(name, _webp(rgba))


def read_sog(path: str | Path) -> tuple[dict, int]:
    """(Gaussians in the capture's coordinates, SH degree) of a .sog bundle (SOG versions 1-2, through gsply)."""
    from gsply.sog_reader import sogread

    return from_gsply(sogread(Path(path)))


FORMAT = SplatFormat(name="PlayCanvas .sog (SOG version 2)", opens="SuperSplat, the PlayCanvas engine, Spark",
                     max_sh=3, write=write_sog, read=read_sog)
