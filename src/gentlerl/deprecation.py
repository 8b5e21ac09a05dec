"""Deprecated names: an old name warns and forwards to its new one for one release.

A public name that moves keeps working under its old name until :data:`REMOVED_IN`: a package's
moved name through :func:`gentlerl.lazy.lazy_exports` (``deprecated=``), a moved method through
:func:`moved_method`. Each use warns once, with one line naming the old name, the new one and the
release that removes it.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

#: The release that removes the names deprecated in this one.
REMOVED_IN = "0.3.0"


def deprecation_message(old: str, new: str) -> str:
    """The one line a deprecated name warns with: ``old``, ``new`` and :data:`REMOVED_IN`."""
    return f"{old} is deprecated, use {new}; it will be removed in {REMOVED_IN}"


def warn_deprecated(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn that ``old`` is deprecated for ``new`` (a ``DeprecationWarning``); the default
    ``stacklevel`` points at the code that used ``old`` through a shim calling this."""
    warnings.warn(deprecation_message(old, new), DeprecationWarning, stacklevel=stacklevel)


def moved_method(old: str, new: str, *, attribute: bool = False) -> Callable[..., Any]:
    """A method ``old`` that warns and forwards to the method ``new`` of the same object, or,
    with ``attribute``, returns its attribute ``new`` (a ``make_x()`` that became ``x``).

    In a class body: ``sampling_transform = moved_method("sampling_transform", "rescore_transform")``.
    """

    def shim(self: Any, *args: Any, **kwargs: Any) -> Any:
        cls = type(self).__name__
        if attribute:
            if args or kwargs:
                raise TypeError(f"{cls}.{old}() takes no arguments")
            warn_deprecated(f"{cls}.{old}()", f"{cls}.{new}")
            return getattr(self, new)
        warn_deprecated(f"{cls}.{old}()", f"{cls}.{new}()")
        return getattr(self, new)(*args, **kwargs)

    shim.__name__ = shim.__qualname__ = old
    shim.__doc__ = f"Deprecated alias of ``{new}``; removed in {REMOVED_IN}."
    return shim
