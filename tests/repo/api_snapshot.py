"""The public API's snapshot: each package's ``__all__`` and the signatures of its names.

``python -m tests.repo.api_snapshot`` prints what changed against ``tests/repo/public_api.json``
(exit 1 on a removal or a signature change); ``--write`` regenerates the file, which a change of
the public API commits together with its CHANGELOG.md entry (CONTRIBUTING.md, "Public API and
deprecations"). ``tests/repo/test_public_api.py`` holds the committed file.

An entry is ``{"kind": ..., "signature": ...}``; a class adds ``"members"``: its public methods'
signatures (``"property"`` / ``"attribute"`` for the others) from gentlerl's classes in its MRO,
not those it inherits from torch or TorchRL. A constant is its type only, not its value.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import re
import sys
from pathlib import Path
from typing import Any

SRC = Path(__file__).resolve().parents[2] / "src" / "gentlerl"
SNAPSHOT = Path(__file__).resolve().with_name("public_api.json")
REGENERATE = "python -m tests.repo.api_snapshot --write"

#: Modules whose names are moving out of the package (to experiments/), so not held here.
EXCLUDED_MODULES = (
    "gentlerl.analysis.criteria",
    "gentlerl.analysis.grid_tables",
    "gentlerl.analysis.method3",
)


def public_packages() -> list[str]:
    """``gentlerl`` and every package under it, by name."""
    subpackages = sorted(p.name for p in SRC.iterdir() if (p / "__init__.py").exists())
    return ["gentlerl", *(f"gentlerl.{name}" for name in subpackages)]


def signature(obj: Any) -> str:
    """``obj``'s signature as text, object addresses in default values removed."""
    try:
        text = str(inspect.signature(obj))
    except (TypeError, ValueError):
        return "<no signature>"
    return re.sub(r" at 0x[0-9a-fA-F]+", "", text)


def _member(cls: type, name: str, raw: Any) -> str:
    if isinstance(raw, property) or type(raw).__name__ == "cached_property":
        return "property"
    if isinstance(raw, (staticmethod, classmethod)) or inspect.isfunction(raw):
        return signature(getattr(cls, name))
    return "attribute"


def class_members(cls: type) -> dict[str, str]:
    """The public members ``cls`` has from gentlerl's classes in its MRO (its own first)."""
    members: dict[str, str] = {}
    for klass in cls.__mro__:
        if not klass.__module__.startswith("gentlerl"):
            continue
        for name, raw in vars(klass).items():
            if not name.startswith("_") and name not in members:
                members[name] = _member(cls, name, raw)
    return dict(sorted(members.items()))


def describe(obj: Any) -> dict[str, Any]:
    """The snapshot entry of one public name."""
    if inspect.ismodule(obj):
        return {"kind": "module"}
    if inspect.isclass(obj):
        return {"kind": "class", "signature": signature(obj), "members": class_members(obj)}
    if callable(obj):
        return {"kind": "function", "signature": signature(obj)}
    return {"kind": "data", "type": type(obj).__name__}


def package_api(package: str) -> dict[str, dict[str, Any]]:
    """``package``'s ``__all__``, each name described; names from :data:`EXCLUDED_MODULES` left
    out."""
    module = importlib.import_module(package)
    if not hasattr(module, "__all__"):
        raise ValueError(f"{package} has no __all__: every public package declares one")
    api = {}
    for name in sorted(module.__all__):
        obj = getattr(module, name)
        if getattr(obj, "__module__", "").startswith(EXCLUDED_MODULES):
            continue
        api[name] = describe(obj)
    return api


def snapshot() -> dict[str, dict[str, dict[str, Any]]]:
    """The public API as it is now: ``{package: {name: entry}}``."""
    return {package: package_api(package) for package in public_packages()}


def _entry_changes(where: str, old: dict[str, Any], new: dict[str, Any]) -> tuple[list, list]:
    breaks, additions = [], []
    for field in ("kind", "signature", "type"):
        if old.get(field) != new.get(field):
            breaks.append(f"{where}: {field} {old.get(field)} -> {new.get(field)}")
    old_members, new_members = old.get("members", {}), new.get("members", {})
    for name, before in old_members.items():
        if name not in new_members:
            breaks.append(f"{where}.{name}: removed")
        elif new_members[name] != before:
            breaks.append(f"{where}.{name}: {before} -> {new_members[name]}")
    additions += [f"{where}.{name}" for name in new_members if name not in old_members]
    return breaks, additions


def compare(old: dict, new: dict) -> tuple[list[str], list[str]]:
    """``(breaks, additions)`` of the API ``new`` against the snapshot ``old``: a break is a
    package, name or member removed or a kind, type or signature changed; an addition is new."""
    breaks: list[str] = []
    additions: list[str] = []
    for package, names in old.items():
        if package not in new:
            breaks.append(f"{package}: removed")
            continue
        for name, entry in names.items():
            where = f"{package}.{name}"
            if name not in new[package]:
                breaks.append(f"{where}: removed")
                continue
            entry_breaks, entry_additions = _entry_changes(where, entry, new[package][name])
            breaks += entry_breaks
            additions += entry_additions
        additions += [f"{package}.{name}" for name in new[package] if name not in names]
    additions += [package for package in new if package not in old]
    return breaks, additions


def load(path: Path = SNAPSHOT) -> dict:
    """The committed snapshot."""
    return json.loads(path.read_text())


def write(api: dict, path: Path = SNAPSHOT) -> None:
    """Write ``api`` as the snapshot (sorted, one entry a line, so that its diff reads)."""
    path.write_text(json.dumps(api, indent=1, sort_keys=True) + "\n")


def main(argv: list[str] | None = None) -> int:
    """Print the changes against the snapshot (exit 1 on a break), or regenerate it."""
    parser = argparse.ArgumentParser(prog="python -m tests.repo.api_snapshot")
    parser.add_argument("--write", action="store_true", help=f"regenerate {SNAPSHOT.name}")
    args = parser.parse_args(argv)
    api = snapshot()
    if args.write:
        write(api)
        print(f"wrote {SNAPSHOT}: {sum(map(len, api.values()))} names in {len(api)} packages")
        return 0
    breaks, additions = compare(load(), api)
    for line in breaks:
        print(f"break: {line}")
    for line in additions:
        print(f"added: {line}")
    return 1 if breaks else 0


if __name__ == "__main__":
    sys.exit(main())
