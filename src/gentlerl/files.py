"""Writing files without following symbolic links that gentlerl did not make; reading YAML
without aliases.

gentlerl never makes a symbolic link. A link planted where a run writes (``run_dir/.lock`` ->
a file elsewhere) would make an ordinary write truncate or overwrite its target, so:

- :func:`write_atomic` writes a new file beside the destination (``mkstemp``: created
  exclusively, never through a link) and renames it over the destination: a link there is
  replaced, its target untouched, and a reader never sees half a file;
- :func:`open_append` appends with ``O_NOFOLLOW``;
- :func:`links_under` lists the links inside a folder (a run directory is checked when a run
  takes it, :class:`~gentlerl.training.run_lock.RunLock`).

gentlerl writes YAML (``config.yaml``, sweep files) without anchors, and :func:`load_yaml` refuses
an alias (``*name``): a few hundred bytes of nested aliases expand to billions of values in
whatever walks them (a "billion laughs"), and no file of gentlerl's needs one.
"""

from __future__ import annotations

import errno
import os
import re
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import yaml


class LinkRefusedError(OSError):
    """A write would have gone through a symbolic link gentlerl did not make."""


def write_atomic(
    path: str | os.PathLike,
    data: str | bytes | Callable[[IO], None],
    *,
    newline: str | None = None,
    binary: bool = False,
) -> None:
    """``path`` holding ``data`` (text, bytes, or ``data(file)`` writing into the open file, a
    binary one with ``binary``), written to a temporary file in its folder, flushed to disk, then
    renamed over ``path``."""
    path = Path(path)
    binary = binary or isinstance(data, bytes)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb" if binary else "w", newline=None if binary else newline) as f:
            if callable(data):
                data(f)
            else:
                f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def open_append(path: str | os.PathLike, *, newline: str | None = None) -> IO[str]:
    """``path`` opened to append text (created if absent), refused if it is a symbolic link."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise LinkRefusedError(
                errno.ELOOP, f"{os.fspath(path)} is a symbolic link: gentlerl writes no file "
                "through a link it did not make; remove it",
            ) from None  # fmt: skip
        raise
    return os.fdopen(fd, "a", newline=newline)


def links_under(root: str | os.PathLike, limit: int = 100_000) -> list[Path]:
    """The symbolic links inside ``root`` (``root`` itself not counted, links not followed),
    looking at no more than ``limit`` entries."""
    found, seen = [], 0
    for folder, dirs, files in os.walk(root, followlinks=False):
        for name in (*dirs, *files):
            seen += 1
            if os.path.islink(os.path.join(folder, name)):
                found.append(Path(folder, name))
        if seen >= limit:
            break
    return found


def folder_link_problem(path: str | os.PathLike, name: str = "run_dir") -> str | None:
    """Why the folder ``path`` cannot take a run's files: it is itself a symbolic link (a planted
    seed folder or cell pointing elsewhere); ``None`` when it is not. Checked before anything is
    written, by the run lock, seed groups and suites."""
    if os.path.islink(path):
        return (
            f"{name}={os.fspath(path)!r} is a symbolic link: a run writes only into folders it "
            f"makes, never through a link; remove it or choose another {name}"
        )
    return None


class _NoAliasLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses aliases (``*name``) where they are composed and reads
    only ``true`` / ``false`` as booleans (YAML 1.2's core schema): YAML 1.1's ``yes``, ``no``,
    ``on``, ``off`` stay words, which a boolean setting then refuses, as the command line does."""

    yaml_implicit_resolvers = {
        first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:bool"]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, f"YAML aliases are not accepted (*{event.anchor})", event.start_mark
            )
        return super().compose_node(parent, index)


_NoAliasLoader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)


#: The largest YAML file gentlerl reads (its configs and sweep files are a few KB).
MAX_YAML_BYTES = 1 << 20


def load_yaml(text: str) -> Any:
    """``yaml.safe_load(text)`` with aliases refused and at most :data:`MAX_YAML_BYTES` of text;
    both raise ``yaml.YAMLError`` (the callers' "not valid YAML" line)."""
    if len(text) > MAX_YAML_BYTES:
        raise yaml.YAMLError(f"{len(text):,} characters, over the {MAX_YAML_BYTES:,} read")
    return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
