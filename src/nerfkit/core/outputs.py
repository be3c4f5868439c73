"""Where a verb writes: checked before any work, so nothing the user had is replaced without --overwrite
and a refused command leaves nothing behind (no folder is created until there is something to write).

    check_new_file(path)     a file that does not exist yet (or --overwrite), in a folder that exists or
                             can be made
    check_new_folder(path)   a folder that does not exist yet or is empty (or --overwrite: its files of the
                             same names are replaced, others stay)
    first_missing(path)      the topmost folder that writing path would create
    staged_folder(path)      write a folder's files beside it and move them in only when all are written, so
                             that a write that fails half way (a full disk, Ctrl-C) leaves path as it was
    replace_with(path, write)  the same for one file: written beside it, renamed over it
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from nerfkit.core.errors import ConfigError


def _check_creatable(path: Path, flag: str) -> None:
    """ConfigError unless path's nearest existing ancestor is a writable folder."""
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ConfigError(f"{flag} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"{flag} {path}: cannot write into {parent} (permission denied)")


def check_new_file(path: Path, overwrite: bool = False, flag: str = "--out") -> Path:
    """path, after checking that writing it replaces nothing unless `overwrite` (see module docstring)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{flag} {path}: is a folder; name a file")
    if path.exists() and not overwrite:
        raise ConfigError(f"{flag} {path}: already exists; pass --overwrite to replace it, or name another file")
    _check_creatable(path, flag)
    return path


def check_new_folder(path: Path, overwrite: bool = False, flag: str = "--out") -> Path:
    """path, after checking that it is a new or empty folder unless `overwrite` (see module docstring)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{flag} {path}: is a file; name a folder")
    if path.is_dir() and any(path.iterdir()) and not overwrite:
        raise ConfigError(f"{flag} {path}: folder is not empty; pass --overwrite to replace what nerfkit writes "
                          f"there, or pick a new folder")
    _check_creatable(path, flag)
    return path


def first_missing(path: Path) -> Path | None:
    """The topmost of path and its ancestors that does not exist (what mkdir(parents=True) would create first),
    or None when path exists."""
    path = Path(path)
    if path.exists():
        return None
    while not path.parent.exists() and path.parent != path.parent.parent:
        path = path.parent
    return path


@contextmanager
def staged_folder(path: Path) -> Iterator[Path]:
    """Yield a hidden sibling folder (.NAME.incomplete) to write path's files into; when the block ends without
    an error they are moved into path (the whole folder renamed when path is new; with --overwrite, files of
    the same names replaced, others left), else the sibling is removed, with any folder made above it. Either
    way path holds the old files or all the new ones, and nothing else is left behind."""
    path = Path(path)
    made = first_missing(path.parent)  # the topmost folder this creates, removed again on failure
    tmp = path.parent / f".{path.name}.incomplete"
    try:  # (the folder is made inside: a Ctrl-C just after mkdir returns leaves nothing either)
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        yield tmp
        if not path.exists():
            os.replace(tmp, path)
        else:
            _move_into(tmp, path)
    except BaseException as e:
        shutil.rmtree(made if made is not None else tmp, ignore_errors=True)
        if isinstance(e, OSError) and isinstance(e.filename, str) and e.filename.startswith(str(tmp)):
            e.filename = str(path) + e.filename[len(str(tmp)):]  # the error names the folder the user asked for
        raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _move_into(src: Path, dst: Path) -> None:
    """Move src's files into the folder dst, replacing those of the same names, folder by folder."""
    for f in sorted(src.iterdir()):
        if f.is_dir() and (dst / f.name).is_dir():
            _move_into(f, dst / f.name)
        else:
            os.replace(f, dst / f.name)


def replace_with(path: Path, write: Callable[[Path], object]) -> Path:
    """Call write(tmp) on a hidden file beside `path` (.NAME.tmp-PID), then rename it over `path`, so that a
    reader, a crash or a Ctrl-C sees the old file or the new one, never a part; on any failure the temporary
    file is removed. Returns path."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
