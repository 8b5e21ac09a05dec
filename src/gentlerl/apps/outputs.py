"""Checks of an output file before the work that produces it (rendering, evaluation episodes)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path


def check_output_file(path: str | os.PathLike, suffixes: Sequence[str] = ()) -> Path:
    """``path`` if a file can be written there, else a ``ValueError`` / ``OSError`` saying why:
    a suffix not in ``suffixes`` (when given), an existing directory, a parent that is not a
    directory, or a folder this process cannot write to. Creates nothing."""
    path = Path(path)
    if suffixes and path.suffix not in suffixes:
        raise ValueError(f"{path}: the file name must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise IsADirectoryError(f"{path} is a directory; give a file name")
    parent = path.parent
    while not parent.exists():  # the nearest folder that exists is where one gets created
        parent = parent.parent
    if not parent.is_dir():
        raise NotADirectoryError(f"{parent} is not a directory, so {path} cannot be written")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise PermissionError(f"cannot write {path}: {parent} is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise PermissionError(f"cannot write {path}: the file is read-only")
    return path
