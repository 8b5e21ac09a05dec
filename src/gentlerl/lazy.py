"""Package namespaces whose modules are imported on first use (PEP 562 ``__getattr__``).

``gentlerl train --help``, config checks and refusals read names and settings only; importing a
package must not import torch, TorchRL or MuJoCo (seconds) before a command needs them.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from gentlerl.deprecation import warn_deprecated


def lazy_exports(
    package: str,
    exports: Mapping[str, Sequence[str]],
    deprecated: Mapping[str, tuple[str, str]] | None = None,
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``(__getattr__, __dir__, __all__)`` of ``package`` exporting ``exports``' names
    (``{module: (name, ...)}``), each module imported when one of its names is first read.
    A package's ``__init__`` assigns them: ``__getattr__, __dir__, __all__ = lazy_exports(...)``.

    ``deprecated`` (``{old_name: (module, new_name)}``): names that moved, still readable here
    until :data:`gentlerl.deprecation.REMOVED_IN`; each read warns and returns ``module.new_name``.
    They are in neither ``__all__`` nor ``dir()``.
    """
    owner = {name: module for module, names in exports.items() for name in names}
    moved = dict(deprecated or {})
    if overlap := sorted(moved.keys() & owner.keys()):
        raise ValueError(f"{package}: {overlap} are both exported and deprecated")

    def __getattr__(name: str) -> Any:
        if name in moved:  # not cached in the package: every read warns
            module, new_name = moved[name]
            if not _import_probe():
                warn_deprecated(f"{package}.{name}", f"{module}.{new_name}")
            return getattr(importlib.import_module(module), new_name)
        if name not in owner:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(owner[name]), name)
        setattr(sys.modules[package], name, value)  # later reads skip this hook
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *owner})

    return __getattr__, __dir__, sorted(owner)


def _import_probe() -> bool:
    """Whether a package ``__getattr__`` runs for importlib's ``hasattr`` probe of ``from package
    import name``, which the statement's own read of the name follows (that one warns, once)."""
    return sys._getframe(2).f_code.co_filename.startswith("<frozen importlib")


def record_missing_pandas() -> None:
    """Make tensordict's per-call probe for pandas a dictionary look-up in a training process.

    ``TensorDict.from_any``, which ``TensorDictModule`` runs on every output, calls
    ``importlib.util.find_spec("pandas")`` each time; without pandas installed that searches
    ``sys.path`` on every call (~70 us, 6 % of a default training run, measured).
    ``sys.modules["pandas"] = None`` is Python's record of a module that cannot be imported.
    Done by a run's process set-up, not at ``import gentlerl`` (a notebook may install pandas
    later); nothing changes where pandas is installed.
    """
    if "pandas" not in sys.modules and importlib.util.find_spec("pandas") is None:
        sys.modules["pandas"] = None
