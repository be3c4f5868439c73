"""PlayCanvas's .sog (splat/formats/sog.py): written here, read back by gsply's SOG reader (not nerfkit's code),
compared attribute by attribute (in the file's Morton order) and by render.

Bounds from what SOG quantises (test_ply.gaussians: 300 Gaussians, so every Gaussian's SH bands are their own
palette entry): positions 16 bits of ln(1 + |x|) over its range, so |dx| <= (range / 65535) (1 + |x|) / 2;
opacity 8 bits of sigmoid; rotations 8 bits of three components in [-1/sqrt2, 1/sqrt2] (each off by at most
1 / (255 sqrt2)); log scales, colours and SH coefficients by 256-entry codebooks (k-means over their values). The
renders, measured: 67.2 dB from the original at degree 0, 58.0 at degree 3 (the codebooks of 900 and 13,500
values); floors 58 and 50.
"""

import io
import json
import zipfile

import numpy as np
import pytest
from PIL import Image
from test_ply import C2W, CAM, gaussians

from nerfkit.core.errors import ConfigError
from nerfkit.core.metrics import psnr
from nerfkit.models.splat.formats import read_gaussians, splat_format
from nerfkit.models.splat.formats import sog
from nerfkit.models.splat.gaussians import render

FLOOR_DEGREE_0, FLOOR_DEGREE_3 = 58.0, 50.0


def _psnr(a, b, degree):
    return float(psnr(np.asarray(render(a, C2W, CAM, sh_degree=degree)["rgb"]),
                      np.asarray(render(b, C2W, CAM, sh_degree=degree)["rgb"])))


def _rotation_gap(a, b):
    """max |a - b| over rows of unit quaternions, q and -q being the same rotation."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    return float(np.minimum(np.abs(a - b).max(1), np.abs(a + b).max(1)).max())


@pytest.mark.smoke  # gsply's SOG reader with imagecodecs, and Pillow's WebP, at their lowest allowed versions
def test_sog_round_trip_holds_every_attribute_within_its_quantisation(tmp_path):
    p = gaussians()
    splat_format("a.sog").write(tmp_path / "g.sog", p, 3)
    g, degree, fmt = read_gaussians(tmp_path / "g.sog")
    assert degree == 3 and fmt.name.startswith("PlayCanvas .sog")
    o = sog.morton_order(np.asarray(p["means"], np.float64))
    q = {k: np.asarray(v, np.float64)[o] for k, v in p.items()}
    n = np.sign(q["means"]) * np.log1p(np.abs(q["means"]))
    step = (n.max(0) - n.min(0)) / 65535
    assert np.all(np.abs(g["means"] - q["means"]) <= 0.5 * step * (1 + np.abs(q["means"])) + 1e-6)
    sig = lambda x: 1 / (1 + np.exp(-x))  # noqa: E731
    assert np.abs(sig(g["opacity"]) - sig(q["opacity"])).max() <= 0.5 / 255 + 1e-6
    assert _rotation_gap(g["quats"], q["quats"]) <= 2.0 / 255  # three off by 1 / (255 sqrt2), the fourth from them
    assert np.abs(g["log_scales"] - q["log_scales"]).mean() <= 0.01  # the codebook's 256 entries for 900 values
    assert np.abs(g["sh_rest"] - q["sh_rest"]).mean() <= 0.01
    assert _psnr(p, g, 0) >= FLOOR_DEGREE_0
    assert _psnr(p, g, 3) >= FLOOR_DEGREE_3


def test_sog_bundle_is_what_playcanvas_reads(tmp_path):
    p = gaussians()
    splat_format("a.sog").write(tmp_path / "g.sog", p, 2)
    with zipfile.ZipFile(tmp_path / "g.sog") as z:
        meta = json.loads(z.read("meta.json"))
        names = set(z.namelist())
        quats = np.asarray(Image.open(io.BytesIO(z.read("quats.webp"))))
        cent = Image.open(io.BytesIO(z.read("shN_centroids.webp")))
    assert meta["version"] == 2 and meta["count"] == 300
    assert meta["shN"]["bands"] == 2 and meta["shN"]["count"] == 300 and cent.size == (64 * 8, 5)
    assert all(len(meta[k]["codebook"]) == 256 for k in ("scales", "sh0", "shN"))
    assert names == {"meta.json", *sog._IMAGES, *sog._SH_IMAGES}
    h, w, _ = quats.shape
    assert w % 4 == 0 and h % 4 == 0 and w * h >= 300
    assert set(np.unique(quats.reshape(-1, 4)[:300, 3])) <= {252, 253, 254, 255}  # the dropped component's index


def test_sog_palette_clusters_when_the_gaussians_outnumber_it(tmp_path, monkeypatch):
    """300 Gaussians whose SH bands are 8 patterns and a little noise, a palette of 32: k-means finds the patterns
    and every Gaussian is labelled with its own (a palette of one would leave the spread between patterns)."""
    p = gaussians()
    rng = np.random.default_rng(1)
    rest = rng.normal(0, 0.5, (8, 15, 3))[rng.integers(0, 8, 300)] + rng.normal(0, 0.01, (300, 15, 3))
    p["sh_rest"] = rest.astype(np.float32)
    monkeypatch.setattr(sog, "PALETTE", 32)
    splat_format("a.sog").write(tmp_path / "g.sog", p, 3)
    g, _, _ = read_gaussians(tmp_path / "g.sog")
    with zipfile.ZipFile(tmp_path / "g.sog") as z:
        assert json.loads(z.read("meta.json"))["shN"]["count"] == 32
    o = sog.morton_order(np.asarray(p["means"], np.float64))
    err = np.abs(g["sh_rest"] - rest[o]).mean()
    one = np.abs(rest - rest.mean(0)).mean()
    assert len(np.unique(np.asarray(g["sh_rest"]).reshape(300, -1), axis=0)) <= 32
    assert err < 0.1 * one, (err, one)


def test_sog_degree_zero_has_no_palette(tmp_path):
    p = gaussians()
    splat_format("a.sog").write(tmp_path / "g.sog", p, 0)
    g, degree, _ = read_gaussians(tmp_path / "g.sog")
    assert degree == 0 and not np.asarray(g["sh_rest"]).any()
    assert _psnr(p, g, 0) >= FLOOR_DEGREE_0


def test_truncated_sog_is_refused_in_one_line(tmp_path):
    p = gaussians()
    splat_format("a.sog").write(tmp_path / "g.sog", p, 3)
    data = (tmp_path / "g.sog").read_bytes()
    (tmp_path / "cut.sog").write_bytes(data[: len(data) // 2])
    with pytest.raises(ConfigError, match=r"cut\.sog: not a usable PlayCanvas \.sog .* file: ") as e:
        read_gaussians(tmp_path / "cut.sog")
    assert "\n" not in str(e.value)
