"""Where a verb writes: checked before any work, so nothing the user had is replaced without --overwrite
and a refused command leaves nothing behind (no folder is created until there is something to write).

    check_new_file(path)     a file that does not exist yet (or --overwrite), in a folder that exists or
                             can be made
    check_new_folder(path)   a folder that does not exist yet or is empty (or --overwrite: its files of the
                             same names are replaced, others stay)
"""

from __future__ import annotations

import os
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
