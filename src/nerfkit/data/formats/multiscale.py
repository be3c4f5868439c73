"""mip-NeRF's multiscale Blender layout, and `nerfkit make-multiscale` that writes it.

A multiscale scene holds every image of a Blender scene at L levels, 1, 1/2, 1/4, 1/8 of the
full resolution (mip-NeRF, Barron et al. 2021, sec. 5): level l has width W_l = W // 2^l and
focal f_l = f / 2^l, so its pixel (i, j) covers the 2^l x 2^l full-resolution pixels it
averages (box filter), and the ray through its centre is the mean of theirs (pinhole rays are
affine in the pixel coordinates). One file describes it, as mip-NeRF's converter writes it:

    metadata.json   {split: {"file_path": [...], "cam2world": [4x4, ...], "width": [...],
                     "height": [...], "focal": [...], "label": [level, ...],
                     "lossmult": [4^level, ...] (the pixel's area, for area-weighted losses),
                     "near": [...], "far": [...]}}
    {split}/{name}_d{l}.png   RGBA

Frames are listed level by level (all views at level 0, then level 1, ...). nerfkit reads the
split `{split}` as every level, `{split}_d{l}` as level l alone, and a slice selects views:
`val[50:100]` is views 50-99 at every level. Colours are averaged with their alpha
(premultiplied), so that compositing on any background commutes with the averaging.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import ConfigError, DataError
from nerfkit.core.outputs import staged_folder
from nerfkit.data.capture import Capture, Frame, parse_split_spec
from nerfkit.data.formats.blender import (
    check_pose,
    frame_image_path,
    is_blender,
    iter_frames,
)
from nerfkit.data.images import area_downscale, one_line, read_rgba
from nerfkit.rays.cameras import Camera

METADATA = "metadata.json"
KEYS = ("file_path", "cam2world", "width", "height", "focal", "label")


def is_multiscale(root: Path) -> bool:
    return (Path(root) / METADATA).is_file()


def read_metadata(root: Path) -> dict:
    path = Path(root) / METADATA
    try:
        meta = json.loads(path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        raise DataError(f"{path}: not readable multiscale metadata ({one_line(e)}); re-run nerfkit make-multiscale")
    if not isinstance(meta, dict) or not meta:
        raise DataError(f"{path}: expected {{split: {{{', '.join(KEYS)}, ...}}}}")
    for split, m in meta.items():
        if not isinstance(m, dict) or any(not isinstance(m.get(k), list) for k in KEYS):
            raise DataError(f"{path}: split {split!r} needs the lists {', '.join(KEYS)}")
        if len({len(m[k]) for k in KEYS}) != 1:
            raise DataError(f"{path}: split {split!r}: the lists {', '.join(KEYS)} differ in length")
    return meta


def read_multiscale(root: str | Path) -> Capture:
    """The frames of every split and level (see the module docstring), as a Blender-format Capture."""
    root = Path(root)
    path = root / METADATA
    splits, source, levels = {}, {}, {}
    for split, m in read_metadata(root).items():
        by_level: dict[int, list[Frame]] = {}
        for k, (fp, c2w, w, h, f, lvl) in enumerate(zip(*(m[key] for key in KEYS))):
            where = f"{path} {split} frame {k}"
            cam = Camera(int(w), int(h), float(f), float(f), 0.5 * int(w), 0.5 * int(h))
            by_level.setdefault(int(lvl), []).append(Frame(root / fp, check_pose(c2w, where), cam, None, where))
        counts = {len(v) for v in by_level.values()}
        if sorted(by_level) != list(range(len(by_level))) or len(counts) != 1:
            raise DataError(f"{path}: split {split!r} must hold the same views at levels 0..L-1 (labels)")
        levels[split] = len(by_level)
        splits[split] = [fr for lvl in sorted(by_level) for fr in by_level[lvl]]
        for lvl, frames in by_level.items():
            splits[f"{split}_d{lvl}"] = frames
        for name in [split] + [f"{split}_d{lvl}" for lvl in by_level]:
            source[name] = str(path)
    return Capture(root, "blender", splits, normalize=False, alpha=True, own_splits=True, source=source,
                   levels=levels)


def level_specs(cap: Capture, spec: str) -> list[tuple[int, str]] | None:
    """[(level, spec of that level)] when `spec` names multiscale splits (each level evaluated apart),
    else None. "val[50:100]" -> [(0, "val_d0[50:100]"), (1, "val_d1[50:100]"), ...]."""
    items = parse_split_spec(spec)
    n = {cap.levels.get(i.split, 1) for i in items}
    if n == {1}:
        return None
    if len(n) != 1:
        raise DataError(f"split spec {spec!r} mixes multiscale splits with single-scale ones; evaluate them apart")
    return [(lvl, ",".join(str(replace(i, split=f"{i.split}_d{lvl}")) for i in items)) for lvl in range(n.pop())]


def make_multiscale(src: Path, out: Path, levels: int = 4, progress: bool = True) -> dict:
    """Write the Blender scene `src` (every transforms_*.json) in the multiscale layout into `out`."""
    src, out = Path(src), Path(out)
    if not 1 <= levels <= 8:
        raise ConfigError(f"--levels must be between 1 and 8 (got {levels})")
    if not is_blender(src):
        raise ConfigError(f"{src}: no transforms_*.json; make-multiscale converts a Blender-format scene")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out {out}: exists and is not an empty folder; pick a new one")
    splits = sorted(p.name[len("transforms_"):-len(".json")] for p in src.glob("transforms_*.json"))
    meta, n_images = {}, 0
    with staged_folder(out) as tmp:  # all the files or none (a full disk, Ctrl-C, an image refused half way)
        for split in splits:
            frames = list(iter_frames(src, split))
            m = {k: [] for k in (*KEYS, "lossmult", "near", "far")}
            per_level = [[] for _ in range(levels)]
            for where, frame, pose, fov, _ in tqdm(frames, desc=f"make-multiscale {split}", disable=not progress):
                image = frame_image_path(src, frame["file_path"], where)
                rgb, a = read_rgba(image)
                h, w = a.shape
                if h % 2 ** (levels - 1) or w % 2 ** (levels - 1):
                    raise ConfigError(f"{image}: {w}x{h} is not divisible by {2 ** (levels - 1)}; use fewer --levels")
                focal = 0.5 * w / np.tan(0.5 * fov)
                for lvl in range(levels):
                    s = 2**lvl
                    a_l = area_downscale(a, s)
                    rgb_l = area_downscale(rgb * a[..., None], s) / np.maximum(a_l, 1e-8)[..., None]
                    rgba = np.concatenate([np.clip(rgb_l, 0, 1), a_l[..., None]], -1)
                    rel = f"{split}/{Path(frame['file_path']).name}_d{lvl}.png"
                    (tmp / split).mkdir(parents=True, exist_ok=True)
                    iio.imwrite(tmp / rel, np.round(rgba * 255).astype(np.uint8))
                    per_level[lvl].append((rel, pose.tolist(), w // s, h // s, focal / s, lvl, float(s * s)))
            for row in (row for rows in per_level for row in rows):
                for key, v in zip((*KEYS, "lossmult", "near", "far"), (*row, 2.0, 6.0)):
                    m[key].append(v)
            meta[split] = m
            n_images += len(frames) * levels
        (tmp / METADATA).write_text(json.dumps(meta))
    return {"splits": splits, "images": n_images, "levels": levels, "out": str(out)}


# -- the format (data/formats/registry.py): a Blender scene in mip-NeRF's multiscale layout -----------
NAME = "blender"
LOOKS_FOR = "metadata.json (multiscale)"


def detect(root: Path) -> bool:
    return is_multiscale(root) and not is_blender(root)


def read(root: Path, spec: str, holdout_every: int, masks: bool) -> Capture:
    return read_multiscale(root)
