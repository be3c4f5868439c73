"""What every export does with its output file: the capture-frame transform of exported points, the
--out check before any work, and the atomic write (of several files together). The trained run and its export
records are run/folder.py's (RunFolder)."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.core.outputs import check_new_file, first_missing


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


def refuse_own_input(out: Path | None, run_dir: Path, data: Path | None = None, flag: str = "--out") -> None:
    """ConfigError when `out` would replace a file the export reads: the run's config.json, scene.json or a
    checkpoint, or a file of the capture (`data`, else the folder the run was trained on)."""
    if out is None:
        return
    o, run = Path(out).resolve(), Path(run_dir).resolve()
    if o in (run / "config.json", run / "scene.json") or o.is_relative_to(run / "checkpoints"):
        raise ConfigError(f"{flag} {out}: is one of the run's own files, which the export reads; name another file")
    if data is None:
        try:
            data = Path(json.loads((run / "scene.json").read_text())["data_dir"])
        except (OSError, ValueError, KeyError, TypeError):
            return  # the export's own loading names what is wrong with the run
    if o.exists() and o.is_relative_to(Path(data).resolve()):
        raise ConfigError(f"{flag} {out}: is a file of the capture {data}, which the export reads; name another file")


def write_atomic(out: Path, write) -> None:
    """Call write(tmp_path) on a temporary file beside `out` (same extension), then rename it over
    `out`, so an interrupted export never leaves a truncated file (write_together)."""
    write_together([(Path(out), write)])


def write_together(files: list[tuple[Path, Callable[[Path], object]]]) -> None:
    """For each (out, write): write(tmp) on a temporary file beside out (.STEM.partial.EXT); once every one is
    written, rename each over its out. A failure before that (a full disk, Ctrl-C) removes the temporaries and
    any folder made for them, and leaves every out as it was; an OSError then names the out, not the
    temporary."""
    made = [top for out, _ in files if (top := first_missing(out.parent)) is not None]
    tmps = [out.with_name(f".{out.stem}.partial{out.suffix}") for out, _ in files]
    try:  # (the folders are made inside: a Ctrl-C just after a mkdir leaves nothing either)
        for out, _ in files:
            out.parent.mkdir(parents=True, exist_ok=True)
        for (out, write), tmp in zip(files, tmps):
            try:
                write(tmp)
            except OSError as e:
                if e.filename is not None and Path(e.filename) == tmp:
                    e.filename = str(out)  # the error names the file the user asked for
                raise
        for (out, _), tmp in zip(files, tmps):
            os.replace(tmp, out)
    except BaseException:
        for top in made:
            shutil.rmtree(top, ignore_errors=True)
        raise
    finally:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)
