"""Reading a sweep file safely: every key a config field, every value a plain number or name.

Sweep keys become hydra overrides and values become folder names, so a key like
``+hydra.callbacks.x._target_`` would run code and a value like ``r/../../x`` would write outside
``--out``: both are refused before anything runs, in one line naming the key or value. Nor does a
sweep choose where its runs execute: ``collector.kind=ray`` and ``collector.ray_address`` send
the trainer's code to a Ray cluster, which runs what it is sent and answers with pickles, so they
are refused unless the command line allows them (``allow_ray``). ``--set`` items follow the same
rules as the file.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from gentlerl.files import load_yaml, load_yaml_file

__all__ = [
    "check_boolean",
    "check_cluster",
    "check_key",
    "check_value",
    "load_sweep",
    "nested_overrides",
    "parse_set",
    "sweepable_fields",
]

#: What a string in a sweep may hold: a name or a number, never a path separator, a hydra
#: interpolation (``${...}``), a list or another override (``,`` ``=`` ``[`` spaces, quotes).
_SAFE_STRING = re.compile(r"[A-Za-z0-9_.:+-]+")
#: Fields the runner sets itself for each grid point.
_RUNNER_FIELDS = ("run_dir", "resume")
#: The words YAML 1.1 reads as booleans (``load_yaml`` reads only ``true`` / ``false``).
_YAML11_BOOLEANS = frozenset({"y", "n", "yes", "no", "on", "off"})
#: The command-line flag of ``gentlerl sweep`` that lets a sweep set the Ray collector.
ALLOW_RAY_FLAG = "--allow-ray-collector"


def sweepable_fields() -> dict[str, str]:
    """Config fields a sweep may vary (``group.field`` -> its type), not ``run_dir`` / ``resume``
    (the runner sets them) nor the mapping ``env.kwargs``."""
    from gentlerl.training.config import iter_fields

    return {
        name: str(f.type)
        for name, f in iter_fields()
        if name not in _RUNNER_FIELDS and not str(f.type).startswith("dict")
    }


def check_key(key: str, where: str) -> None:
    """Refuse a sweep key that is not a config field (``hydra.*``, ``_target_``, ``+`` ...)."""
    if key in _RUNNER_FIELDS:
        raise ValueError(f"{where}: {key!r} cannot be swept (the sweep runner sets it per point)")
    if key not in sweepable_fields():
        raise ValueError(
            f"{where}: unknown key {key!r}: sweep keys are config fields (group.field, see "
            "gentlerl train --help); hydra.*, _target_ and +/++ additions are refused"
        )


def check_value(key: str, value: Any, where: str) -> None:
    """Refuse a value that is not a number, a boolean, null, a plain name or a flat list of them."""
    if isinstance(value, list | tuple):
        for element in value:
            if isinstance(element, list | tuple):
                raise ValueError(f"{where}: {key}={value!r}: nested lists are not sweep values")
            check_value(key, element, where)
    elif isinstance(value, str):
        if not _SAFE_STRING.fullmatch(value) or value in (".", ".."):
            raise ValueError(
                f"{where}: {key}={value!r}: a string value may hold only letters, digits and "
                "'_.:+-' (no '/', '$', ',', '=', spaces, quotes or brackets)"
            )
    elif not (value is None or isinstance(value, bool | int | float)):
        raise ValueError(f"{where}: {key}={value!r}: expected a number, a name or a list of them")


def check_boolean(key: str, value: Any, where: str) -> None:
    """Refuse a value of a boolean field that is not ``true`` or ``false``: ``load_yaml`` reads
    YAML 1.1's ``yes`` / ``on`` ... as words, and a number is not a boolean. A field that also
    takes a word (``collector.overlap``: ``auto``) refuses those words and numbers only."""
    kind = sweepable_fields().get(key, "")
    if "bool" not in kind.split(" | ") or isinstance(value, bool):
        return
    if kind == "bool" or isinstance(value, int | float) or str(value).lower() in _YAML11_BOOLEANS:
        raise ValueError(f"{where}: {key}={value} must be true or false")


def check_cluster(key: str, value: Any, where: str, allow_ray: bool = False) -> None:
    """Refuse ``collector.kind=ray`` or a ``collector.ray_address`` (where the runs would execute
    code) unless ``allow_ray``."""
    if allow_ray or not (
        (key == "collector.kind" and value == "ray")
        or (key == "collector.ray_address" and value is not None)
    ):
        return
    raise ValueError(
        f"{where}: {key}={value!r}: a sweep does not choose where its runs execute (a Ray cluster "
        f"runs the code it is sent); pass {ALLOW_RAY_FLAG} to let the sweep file and --set use "
        "the Ray collector"
    )


def load_sweep(path: str | Path, allow_ray: bool = False) -> dict[str, list[Any]]:
    """``parameters`` of a wandb grid sweep file as name -> list of values, every key a config
    field and every value plain (:func:`check_key`, :func:`check_value`), none choosing a Ray
    cluster unless ``allow_ray`` (:func:`check_cluster`)."""
    try:
        spec = load_yaml_file(path)
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    if not isinstance(spec, dict):
        raise ValueError(
            f"{path}: expected a mapping with `parameters:`, got {type(spec).__name__}"
        )
    if spec.get("method", "grid") != "grid":
        raise ValueError(f"{path}: only grid sweeps run locally, got method={spec.get('method')!r}")
    parameters = spec.get("parameters") or {}
    if not isinstance(parameters, dict):
        raise ValueError(f"{path}: `parameters:` must be a mapping of key -> {{values: [...]}}")
    grid = {}
    for name, param in parameters.items():
        check_key(str(name), str(path))
        if isinstance(param, dict) and isinstance(param.get("values"), list) and param["values"]:
            grid[name] = list(param["values"])
        elif isinstance(param, dict) and "value" in param:
            grid[name] = [param["value"]]
        else:
            raise ValueError(
                f"{path}: parameter {name!r} needs `values:` (a non-empty list) or `value:`, "
                f"got {param!r}"
            )
        for value in grid[name]:
            check_value(name, value, str(path))
            check_boolean(str(name), value, str(path))
            check_cluster(str(name), value, str(path), allow_ray)
    if not grid:
        raise ValueError(f"{path}: no parameters")
    return grid


def parse_set(items: Sequence[str], allow_ray: bool = False) -> list[tuple[str, Any]]:
    """``--set`` items as ``(key, value)``, each value read as YAML and held to a sweep file's
    rules: ``field=value`` for a config field (or ``+env.kwargs.NAME=value``, how a task keyword
    is added), a plain value (no ``${...}`` interpolation), a boolean field ``true`` or
    ``false`` (:func:`check_boolean`), no Ray collector unless ``allow_ray``."""
    parsed = []
    for item in items:
        key, sep, text = item.partition("=")
        where = f"--set {item!r}"
        if not sep:
            raise ValueError(f"{where}: expected FIELD=VALUE")
        if not re.fullmatch(r"\+env\.kwargs\.[A-Za-z_][A-Za-z0-9_]*", key):
            check_key(key, where)
        try:
            value = load_yaml(text)
        except yaml.YAMLError:
            raise ValueError(f"{where}: the value is not a plain number, name or list") from None
        check_value(key, value, where)
        check_boolean(key, value, where)
        check_cluster(key, value, where, allow_ray)
        parsed.append((key, value))
    return parsed


def point_problem(
    point: Sequence[tuple[str, Any]], extra: Sequence[tuple[str, Any]], scale: str | None
) -> str | None:
    """Why the config of a grid ``point`` (with the parsed ``--set`` items ``extra``,
    :func:`parse_set`) is invalid, in one line, or ``None``."""
    from gentlerl.training.config import make_config

    overrides = nested_overrides([*point, *extra])
    try:
        make_config(overrides.pop("scale", scale or "cpu"), **overrides)
    except (ValueError, TypeError) as err:
        lines = [line.strip().removeprefix("- ") for line in str(err).splitlines()]
        return "; ".join(line for line in lines[1:] if line) or lines[0]
    return None


def nested_overrides(pairs: Sequence[tuple[str, Any]]) -> dict[str, Any]:
    """``(group.field, value)`` pairs (:func:`parse_set`'s) as the nested mapping
    :func:`~gentlerl.training.config.make_config` takes (``scale`` stays a top-level key)."""
    overrides: dict[str, Any] = {}
    for key, value in pairs:
        *groups, name = key.lstrip("+").split(".")
        target = overrides
        for group in groups:
            target = target.setdefault(group, {})
        target[name] = value
    return overrides
