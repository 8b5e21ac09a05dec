"""How a command refuses: one line on stderr, the traceback only when asked (``GENTLERL_DEBUG``).

Shared by the ``gentlerl`` command and the ``gentlerl-train`` app; it imports nothing of
gentlerl, so both can use it without importing each other.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

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


def interrupted(err: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C (or :class:`Terminated`) that ``err`` is or was raised while handling, else
    ``None`` (a ``KeyboardInterrupt`` that struck inside library code can surface as another
    error: it must still read as one)."""
    return next((e for e in causes(err) if isinstance(e, KeyboardInterrupt)), None)


def causes(err: BaseException) -> list[BaseException]:
    """``err``, then the error it was raised from or while handling, and so on."""
    chain: list[BaseException] = []
    current: BaseException | None = err
    while current is not None and all(current is not seen for seen in chain):
        chain.append(current)
        current = current.__cause__ or current.__context__
    return chain


class Terminated(KeyboardInterrupt):
    """A ``SIGTERM``, raised where a Ctrl-C would be, so that a run it stops cleans up as on
    Ctrl-C (collector processes ended, the checkpoint left intact, the run lock released)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def exit_status(interrupt: KeyboardInterrupt) -> int:
    """The exit status of a command stopped by ``interrupt``: 128 + the signal's number."""
    return 128 + (interrupt.signum if isinstance(interrupt, Terminated) else signal.SIGINT)


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, ``SIGTERM`` raises :class:`Terminated` (in the main thread; elsewhere
    signals cannot be handled and the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum: int, frame: object) -> None:
        raise Terminated(signum)

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
