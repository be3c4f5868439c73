"""What every export does with its output file: the capture-frame transform of exported points, the
--out check before any work, and the atomic write. The trained run and its export records are
run/folder.py's (RunFolder)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.core.outputs import check_new_file


def to_capture(points: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """Capture-frame points x = M^-1 [x_n, 1] of normalised points x_n [N, 3] (float64 math)."""
    inv = np.linalg.inv(np.asarray(transform, np.float64))
    return (np.asarray(points, np.float64) @ inv[:3, :3].T + inv[:3, 3]).astype(np.float32)


def check_out(out: Path, suffixes: tuple[str, ...], overwrite: bool = False, flag: str = "--out") -> Path:
    """The output path, checked before any work: a known extension, nothing replaced unless `overwrite`,
    a folder that exists or can be made (made only when the file is written: write_atomic)."""
    out = Path(out)
    if out.suffix.lower() not in suffixes:
        raise ConfigError(f"{flag} {out}: unsupported extension {out.suffix or '(none)'!r}; use "
                          + ", ".join(suffixes))
    if out.is_dir():
        raise ConfigError(f"{flag} {out}: is a folder; name a file such as {out / ('export' + suffixes[0])}")
    return check_new_file(out, overwrite, flag)


def write_atomic(out: Path, write) -> None:
    """Call write(tmp_path) on a temporary file beside `out` (same extension), then rename it over
    `out`, so an interrupted export never leaves a truncated file."""
    tmp = out.with_name(f".{out.stem}.partial{out.suffix}")
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        write(tmp)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
