"""How a command refuses: one line on stderr, the traceback only when asked (``GENTLERL_DEBUG``).

Shared by the ``gentlerl`` command and the ``gentlerl-train`` app; it imports nothing of
gentlerl, so both can use it without importing each other.
"""

from __future__ import annotations

import os

#: Set (to anything but "" or "0") to see the traceback of a refusal or crash.
DEBUG_ENV = "GENTLERL_DEBUG"


def debugging() -> bool:
    """Whether ``GENTLERL_DEBUG`` (or ``--debug``, which sets it) asks for tracebacks."""
    return os.environ.get(DEBUG_ENV, "") not in ("", "0")


def one_line(err: BaseException) -> str:
    """``err`` as one line: its message's lines joined (a bad input's own message), prefixed by
    its type unless it is a refusal of bad input (``ValueError``, ``OSError``, ``TimeoutError``),
    and for anything else a hint to rerun with ``GENTLERL_DEBUG=1``."""
    message = ""
    for line in (line.strip() for line in str(err).splitlines() if line.strip()):
        sep = "" if not message else " " if message.endswith(":") else "; "
        message += sep + line.removeprefix("- ")
    if isinstance(err, ValueError | OSError | TimeoutError):
        return message or type(err).__name__
    return f"{type(err).__name__}: {message} ({DEBUG_ENV}=1 shows the traceback)"


def interrupted(err: BaseException) -> bool:
    """Whether ``err`` is, or was raised while handling, a Ctrl-C (a ``KeyboardInterrupt`` that
    struck inside library code can surface as another error: it must still read as one)."""
    seen: set[int] = set()
    current: BaseException | None = err
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False
