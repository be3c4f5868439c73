"""The capture formats, in the order `--format auto` tries them: adding one is a module with the four
members of `Format` (see blender.py) and one line in FORMATS.

    blender     transforms_{split}.json (+ RGBA PNGs)          formats/blender.py
                or mip-NeRF's multiscale metadata.json          formats/multiscale.py
    nerfstudio  transforms.json (nerfstudio / instant-ngp)       formats/nerfstudio.py
    llff        poses_bounds.npy + images/                       formats/llff.py
    colmap      sparse/0/{cameras,images,points3D}.{bin,txt}     formats/colmap.py
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

from nerfkit.core.errors import DataError
from nerfkit.data.capture import Capture, no_data_folder
from nerfkit.data.formats import blender, colmap, llff, multiscale, nerfstudio


class Format(Protocol):
    """A capture format (a module): its `--format` name, what it looks for (in words, for messages),
    detect(root) -> bool, and read(root, spec, holdout_every, masks) -> Capture (frames by split;
    `spec` names the splits wanted, `holdout_every` makes train/test splits where the format has none,
    `masks` says whether to attach the capture's masks)."""

    NAME: str
    LOOKS_FOR: str

    def detect(self, root: Path) -> bool: ...

    def read(self, root: Path, spec: str, holdout_every: int, masks: bool) -> Capture: ...


FORMATS: list[Format] = [blender, multiscale, nerfstudio, llff, colmap]


def format_names() -> list[str]:
    """The `--format` names, in detection order, each once."""
    return list(dict.fromkeys(f.NAME for f in FORMATS))


def detect_format(root: Path) -> Format:
    """The first format that recognises `root`, or a DataError listing what is looked for."""
    root = Path(root)
    if not root.is_dir():
        raise no_data_folder(root)
    fmt = holds_capture(root)
    if fmt is not None:
        return fmt
    raise DataError(f"{root}: no capture found (looked for {', '.join(f.LOOKS_FOR for f in FORMATS)}); for a folder "
                    f"of photos run `nerfkit process-data images {root} --out DATA` first")


def holds_capture(root: Path) -> Format | None:
    """The format of the capture in folder `root`, or None when it holds none (or is not a folder)."""
    root = Path(root)
    return next((f for f in FORMATS if f.detect(root)), None) if root.is_dir() else None


def format_named(name: str, root: Path) -> Format:
    """The format called `name` (`--format`): of several with one name, the one that recognises `root`."""
    named = [f for f in FORMATS if f.NAME == name]
    if not named:
        raise DataError(f"--format {name!r} is not one of auto, {', '.join(format_names())}")
    return next((f for f in named if f.detect(root)), named[0])
