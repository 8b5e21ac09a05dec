"""Writing and reading files without following symbolic links that gentlerl did not make;
reading YAML without aliases.

gentlerl never makes a symbolic link. A link planted where a run writes (``run_dir/.lock`` ->
a file elsewhere) would make an ordinary write truncate or overwrite its target, so:

- :func:`write_atomic` writes a new file beside the destination (``mkstemp``: created
  exclusively, never through a link) and renames it over the destination: a link there is
  replaced, its target untouched, and a reader never sees half a file;
- :func:`open_append` appends with ``O_NOFOLLOW``;
- :func:`links_under` lists the links inside a folder (a run directory is checked when a run
  takes it, :class:`~gentlerl.training.run_lock.RunLock`).

Every file gentlerl reads goes through :func:`open_checked` (:func:`read_checked` for its whole
text, :func:`load_yaml_file` for YAML): opened without following a link (``O_NOFOLLOW``) and
without blocking (a FIFO would hang the reader), then refused by ``fstat`` *before* any byte is
read when it is not a regular file (a FIFO, ``/dev/zero``, a folder) or is larger than the
reader's cap; each refusal one line naming the file (:class:`FileRefusedError`).

gentlerl writes YAML (``config.yaml``, sweep files) without anchors, and :func:`load_yaml` refuses
an alias (``*name``): a few hundred bytes of nested aliases expand to billions of values in
whatever walks them (a "billion laughs"), and no file of gentlerl's needs one.
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import stat
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


class FileRefusedError(OSError):
    """A file gentlerl will not read: a symbolic link, not a regular file, or over the reader's
    cap (found by ``fstat`` before reading); the message names it, on one line."""


#: The largest YAML file gentlerl reads (its configs and sweep files are a few KB).
MAX_YAML_BYTES = 1 << 20
#: The largest CSV, JSON or log file gentlerl reads (a paper-scale run's largest log is a few MB).
MAX_TEXT_BYTES = 256 << 20

_KINDS = (
    (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
)  # fmt: skip


def open_checked(
    path: str | os.PathLike,
    cap: int | None = MAX_TEXT_BYTES,
    *,
    binary: bool = False,
    newline: str | None = None,
    errors: str | None = None,
) -> IO:
    """``path`` opened to read (text, or bytes with ``binary``), refused before any byte is read
    when it is a symbolic link, not a regular file, or over ``cap`` bytes (``None``: no cap).

    Raises:
        FileNotFoundError: no file at ``path``.
        FileRefusedError: the refusals above, one line naming ``path``.
    """
    name = os.fspath(path)
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise FileRefusedError(
                f"{name} is a symbolic link: gentlerl reads no file through a link it did not "
                "make; give the file itself"
            ) from None
        raise
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = next((k for test, k in _KINDS if test(info.st_mode)), "not a regular file")
            raise FileRefusedError(
                f"{name} is {kind}, not a regular file: gentlerl reads only files"
            )
        if cap is not None and info.st_size > cap:
            raise FileRefusedError(
                f"{name} is {info.st_size:,} bytes, over the {cap:,} this reader takes: not a "
                "file gentlerl wrote"
            )
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    except BaseException:
        os.close(fd)
        raise
    if binary:
        return os.fdopen(fd, "rb")
    return os.fdopen(fd, "r", newline=newline, errors=errors, encoding="utf-8")


def read_checked(
    path: str | os.PathLike, cap: int | None = MAX_TEXT_BYTES, *, errors: str | None = None
) -> str:
    """The text of ``path`` (UTF-8), through :func:`open_checked`; at most ``cap`` bytes are read
    even when the file grows while it is read."""
    with open_checked(path, cap, binary=True) as f:
        data = f.read() if cap is None else f.read(cap + 1)
    if cap is not None and len(data) > cap:
        raise FileRefusedError(
            errno.EFBIG, f"{os.fspath(path)} grew over {cap:,} bytes as it was read"
        )
    try:
        return data.decode("utf-8", errors=errors or "strict")
    except UnicodeDecodeError as err:
        raise FileRefusedError(f"{os.fspath(path)} is not UTF-8 text (byte {err.start})") from None


_TAG = "tag:yaml.org,2002:"
#: YAML 1.2's core schema: the only texts read as booleans, integers and floats. Not YAML 1.1's
#: octal ``010`` (8: here 10, as ``gentlerl train`` reads it), sexagesimal ``1:04`` (64),
#: ``1_000``, ``0x10``, ``yes`` / ``on``, timestamps: those stay words, which a number or boolean
#: setting refuses; ``1e-3`` is a float (YAML 1.1 wanted ``1.0e-3``).
YAML_BOOL = re.compile(r"true|True|TRUE|false|False|FALSE")
YAML_INT = re.compile(r"[-+]?[0-9]+")
YAML_FLOAT = re.compile(
    r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)"
)


#: What a spreadsheet reads as a formula at the start of a cell (CSV injection).
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_safe(value: Any) -> Any:
    """``value`` for a CSV cell a person may open in a spreadsheet: a text starting as a formula
    (:data:`FORMULA_START`, ``=HYPERLINK(...)``) with a leading apostrophe, which shows it as
    text; numbers, and texts that are numbers (``-1.5``), as they are."""
    if isinstance(value, str) and value.startswith(FORMULA_START):
        try:
            float(value)
        except ValueError:
            return "'" + value
    return value


class _NoAliasLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses aliases (``*name``) where they are composed and reads
    booleans and numbers by YAML 1.2's core schema (:data:`YAML_BOOL`, :data:`YAML_INT`,
    :data:`YAML_FLOAT`): YAML 1.1's ``yes``, ``no``, ``on``, ``off``, ``010``, ``1:04`` stay
    words, which a boolean or number setting then refuses, as the command line does; an explicit
    tag on a text that is not one (``!!bool 2``, ``!!int 1:04``) is a YAML error."""

    yaml_implicit_resolvers = {
        first: [
            (tag, rx)
            for tag, rx in resolvers
            if tag not in (f"{_TAG}bool", f"{_TAG}int", f"{_TAG}float", f"{_TAG}timestamp")
        ]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, f"YAML aliases are not accepted (*{event.anchor})", event.start_mark
            )
        return super().compose_node(parent, index)


def _anchored(pattern: re.Pattern[str]) -> re.Pattern[str]:
    return re.compile(f"^(?:{pattern.pattern})$")


# in this order: an integer's text is a float's too
_NoAliasLoader.add_implicit_resolver(f"{_TAG}bool", _anchored(YAML_BOOL), list("tTfF"))
_NoAliasLoader.add_implicit_resolver(f"{_TAG}int", _anchored(YAML_INT), list("-+0123456789"))
_NoAliasLoader.add_implicit_resolver(f"{_TAG}float", _anchored(YAML_FLOAT), list("-+0123456789."))


def _scalar(kind: str, pattern: re.Pattern[str], read: Callable[[str], Any]) -> Callable:
    def construct(loader: yaml.SafeLoader, node: yaml.Node) -> Any:
        text = loader.construct_scalar(node)
        if isinstance(text, str) and pattern.fullmatch(text):
            try:
                return read(text)
            except ValueError:  # an integer of more digits than Python converts
                pass
        raise yaml.constructor.ConstructorError(
            None, None, f"{str(text)[:40]!r} is not {kind} (YAML 1.2 core)", node.start_mark
        )

    return construct


def _float(text: str) -> float:
    special = text.lower().lstrip("+-") in (".inf", ".nan")  # YAML's spelling of inf and nan
    return float(text.replace(".", "", 1) if special else text)


_NoAliasLoader.add_constructor(
    f"{_TAG}bool", _scalar("true or false", YAML_BOOL, lambda t: t.lower() == "true")
)
_NoAliasLoader.add_constructor(f"{_TAG}int", _scalar("an integer", YAML_INT, int))
_NoAliasLoader.add_constructor(f"{_TAG}float", _scalar("a number", YAML_FLOAT, _float))


def _implicit_tag(text: str) -> str:
    """The tag :func:`load_yaml` gives the plain (unquoted) scalar ``text``."""
    for tag, rx in _NoAliasLoader.yaml_implicit_resolvers.get(text[:1] if text else "", []):
        if rx.match(text):
            return tag
    return f"{_TAG}str"


class _Dumper(yaml.SafeDumper):
    """``yaml.SafeDumper`` quoting every string that :func:`load_yaml` (YAML 1.2 core) or a YAML
    1.1 reader would read as something else (``1e-3``, ``010``, ``yes``)."""

    def represent_str(self, data: str) -> yaml.ScalarNode:
        if _implicit_tag(data) != f"{_TAG}str":
            return self.represent_scalar(f"{_TAG}str", data, style="'")
        return super().represent_str(data)


_Dumper.add_representer(str, _Dumper.represent_str)


def dump_yaml(data: Any, **options: Any) -> str:
    """``yaml.safe_dump(data, **options)`` that :func:`load_yaml` reads back as ``data``."""
    return yaml.dump(data, Dumper=_Dumper, **options)


def load_yaml(text: str) -> Any:
    """``yaml.safe_load(text)`` with aliases refused and at most :data:`MAX_YAML_BYTES` of text;
    both raise ``yaml.YAMLError`` (the callers' "not valid YAML" line)."""
    if len(text) > MAX_YAML_BYTES:
        raise yaml.YAMLError(f"{len(text):,} characters, over the {MAX_YAML_BYTES:,} read")
    return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass


def load_yaml_file(path: str | os.PathLike, *, errors: str | None = None) -> Any:
    """:func:`load_yaml` of the file ``path``, read through :func:`read_checked` with the cap
    :data:`MAX_YAML_BYTES` (a link, a FIFO, ``/dev/zero`` or a large file: refused unread)."""
    return load_yaml(read_checked(path, MAX_YAML_BYTES, errors=errors))
