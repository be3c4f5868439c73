"""Gaussians to and from Niantic's .spz (version 3: the gzip container with smallest-three rotations, what
Spark, GaussianSplats3D, SuperSplat and Scaniverse read), through gsply (numpy and numba, from pip).

SPZ quantises every attribute (nianticlabs/spz, load-spz.cc):

    positions   24-bit fixed point, 12 fractional bits (steps of 1/4096 of the capture's unit)
    scales      8 bits over log scales in [-10, 6)  (byte = (s + 10) 16, steps of 1/16)
    rotations   smallest three of the unit quaternion, 9 bits and a sign each
    opacity     8 bits of sigmoid(opacity)
    colour      8 bits of 0.15 sh_dc + 0.5  (sh_dc in [-3.33, 3.33])
    SH 1..3     8 bits of sh / 128 + 0.5  (|sh| < 1), rounded further as Niantic's own writer rounds them
                (its PackOptions sh1Bits, shRestBits), so that gzip finds them repeated: band 1 to 6 bits
                (multiples of 4 of those bytes), bands 2-3 to 5 (multiples of 8), a bit more than its
                defaults (5 and 4), whose rounding cost 0.36 dB on lego's held-out views and 0.42 on maryrose's
                against 0.10 and 0.11 here (2- and 5-minute runs, files 14x / 13x and 12x / 10x under the .ply)

and the whole payload is gzipped: about a tenth of the .ply's size.

Axes: SPZ files are in RUB (x right, y up, z back: OpenGL's, three.js's), the .ply's RDF (x right, y down,
z forward) turned 180 degrees about x: (x, y, z) -> (x, -y, -z), rotations and SH coefficients turned with
them (transform.py). Written and read so, the Gaussians come back in the capture's coordinates.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nerfkit.models.splat.formats import RDF_TO_RUB, REST_OF_DEGREE, SplatFormat, from_gsply, unit_quats
from nerfkit.models.splat.transform import transform_gaussians

SPZ_VERSION = 3
FRACTIONAL_BITS = 12
SH1_BITS, SH_REST_BITS = 6, 5  # the SH bytes' precision (Niantic's writer's PackOptions; the module docstring)


def quantise_sh(rest: np.ndarray) -> np.ndarray:
    """SH bands 1..3 rest [N, K, 3] as Niantic's writer stores them: the byte q = round(128 sh) + 128 rounded to the
    nearest multiple of 2^(8 - bits) (SH1_BITS for band 1's three coefficients, SH_REST_BITS after), clipped to
    0..255, and read back as (q - 128) / 128."""
    rest = np.asarray(rest, np.float64)
    q = np.round(128.0 * rest) + 128.0
    bits = np.where(np.arange(rest.shape[1]) < 3, SH1_BITS, SH_REST_BITS)[None, :, None]
    bucket = 2.0 ** (8 - bits)
    q = np.clip(np.floor((q + bucket / 2) / bucket) * bucket, 0, 255)
    return ((q - 128.0) / 128.0).astype(np.float32)


def write_spz(path: str | Path, g: dict, sh_degree: int = 3) -> None:
    """Write Gaussians (capture coordinates, gaussians.py's layout) to an .spz with `sh_degree` bands."""
    import gsply

    p = transform_gaussians({k: np.asarray(v) for k, v in g.items()}, RDF_TO_RUB)
    k = REST_OF_DEGREE[sh_degree]
    n = len(p["means"])
    data = gsply.GSData(means=p["means"], scales=p["log_scales"], quats=unit_quats(np.asarray(p["quats"], np.float32)), opacities=p["opacity"],
                        sh0=p["sh_dc"].reshape(n, 3), shN=np.ascontiguousarray(quantise_sh(p["sh_rest"][:, :k])),
                        _format=gsply.create_ply_format(sh_degree))
    gsply.write_spz(path, data, version=SPZ_VERSION, fractional_bits=FRACTIONAL_BITS)


def read_spz(path: str | Path) -> tuple[dict, int]:
    """(Gaussians in the capture's coordinates, SH degree) of an .spz (versions 1-3; 4 with zstandard)."""
    import gsply

    p, degree = from_gsply(gsply.read_spz(path))
    return transform_gaussians(p, RDF_TO_RUB), degree


FORMAT = SplatFormat(name="Niantic .spz (version 3)", opens="Spark, GaussianSplats3D, SuperSplat, Scaniverse",
                     max_sh=3, write=write_spz, read=read_spz)
