"""A setting declared once: its default, help, choices, range, and whether a resume may change it.

A config is a dataclass whose fields are made by :func:`setting`; a field whose type is another
such dataclass is a group (``group.field``). The checks here read the declarations, so a new
field is checked without being listed anywhere else.
"""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

#: Valid values of a field: a tuple, or a function listing them (a registry read when asked).
Choices = Callable[[], list] | tuple | None

_NUMBER = r"-?(?:\d+\.?\d*|\.\d+)(?:e-?\d+)?"
_BOUND = re.compile(rf"(>=|>|<=|<) ?({_NUMBER})")
_INTERVAL = re.compile(rf"([\[(])({_NUMBER}), ?({_NUMBER})([\])])")


@dataclass(frozen=True)
class Range:
    """The numbers a field accepts, written as its messages write it: ``">= 1"``, ``"> 0"``,
    ``"(0, 1]"`` or ``"[0, 1]"`` (:meth:`parse`)."""

    text: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    @classmethod
    def parse(cls, text: str) -> Range:
        """The range ``text`` writes; a ``ValueError`` for any other text."""
        if bound := _BOUND.fullmatch(text):
            op, value = bound.group(1), float(bound.group(2))
            if op.startswith(">"):
                return cls(text, low=value, low_open=op == ">")
            return cls(text, high=value, high_open=op == "<")
        if interval := _INTERVAL.fullmatch(text):
            opening, low, high, closing = interval.groups()
            return cls(text, float(low), float(high), opening == "(", closing == ")")
        raise ValueError(f"range {text!r} is not '>= x', '> x', '<= x', '< x' or an interval")

    def __contains__(self, value: float) -> bool:
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def describe(self) -> str:
        """``">= 1"``, or ``"in (0, 1]"`` for an interval."""
        return self.text if self.text[0] in "<>" else f"in {self.text}"


def setting(
    default: Any,
    help: str,
    *,
    choices: Choices = None,
    bounds: str | None = None,
    resumable: bool = False,
    ablation: bool = False,
) -> Any:
    """A dataclass field carrying everything known about it as metadata.

    Args:
        default: its value unless overridden (a dict or list is copied for each instance).
        help: the one line ``gentlerl-train --help`` prints.
        choices: the valid values (a tuple, or a function returning them).
        bounds: the valid numbers, as :class:`Range` parses them (``None`` is always valid for
            a field that may be null; for a list field, each of its values).
        resumable: a resumed run may change it (how long and how fast it goes on, what it
            logs); the other fields shape the saved networks, buffers or rewards.
        ablation: a knob that switches one of gentlerl's changes to the paper off (or a
            variant of it) for an ablation; ``--help`` marks it ``[ablation]``.
    """
    meta = {
        "help": help,
        "choices": choices,
        "bounds": Range.parse(bounds) if bounds is not None else None,
        "resumable": resumable,
        "ablation": ablation,
    }
    if isinstance(default, dict | list):
        return field(default_factory=lambda: type(default)(default), metadata=meta)
    return field(default=default, metadata=meta)


def _leaves(cls: type, prefix: str = "") -> Iterator[tuple[str, dataclasses.Field, Any]]:
    """``(name, field, annotation)`` of every leaf field of the config class ``cls``."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        if isinstance(hint, type) and dataclasses.is_dataclass(hint):
            yield from _leaves(hint, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}", f, hint


def iter_fields(cls: type) -> Iterator[tuple[str, dataclasses.Field]]:
    """``("group.name" or "name", field)`` for every leaf field of the config class ``cls``."""
    for name, f, _ in _leaves(cls):
        yield name, f


def get(config: Any, name: str) -> Any:
    """The value of ``"group.field"`` (or a top-level ``"field"``) of ``config``."""
    value = config
    for part in name.split("."):
        value = getattr(value, part)
    return value


def resumable(cls: type) -> frozenset[str]:
    """The names of the fields of ``cls`` declared ``resumable``."""
    return frozenset(name for name, f in iter_fields(cls) if f.metadata.get("resumable"))


def choices_of(f: dataclasses.Field) -> list | None:
    """The valid values of ``f`` (its choices function called), or ``None`` when any goes."""
    choices = f.metadata.get("choices")
    if choices is None:
        return None
    return list(choices() if callable(choices) else choices)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


#: How a message names what a value of each scalar annotation must be.
_KINDS = {bool: "true or false", int: "an integer", float: "a finite number", str: "a string"}


def describe_type(hint: Any) -> str:
    """What a value of annotation ``hint`` must be, as a message says it: ``"an integer"``,
    ``"a list of integers"``, ``"a list of 2 finite numbers"``, ``"a string or null"``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        kinds = [k for a in args if a is not type(None) for k in describe_type(a).split(" or ")]
        kinds += ["null"] if type(None) in args else []
        return ", ".join(kinds[:-1]) + " or " + kinds[-1]
    if origin is tuple:
        element = _KINDS.get(args[0], "value").removeprefix("an ").removeprefix("a ")
        element = element if element.endswith("false") else f"{element}s"
        count = "" if args[-1] is Ellipsis else f"{len(args)} "
        return f"a list of {count}{element}"
    if origin is dict:
        return "a mapping"
    return _KINDS.get(hint, f"a {getattr(hint, '__name__', hint)}")


def field_hints(cls: type) -> dict[str, Any]:
    """``{"group.name": annotation}`` of every leaf field of the config class ``cls``."""
    return {name: hint for name, _, hint in _leaves(cls)}


def _type_problem(name: str, hint: Any, value: Any) -> str | None:
    """Why ``value`` does not fit the annotation ``hint`` (or is not finite), or ``None``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        alternatives = [a for a in args if a is not type(None)]
        found = [_type_problem(name, a, value) for a in alternatives]
        return None if None in found else found[0]
    fits = {
        bool: isinstance(value, bool),
        int: isinstance(value, int) and not isinstance(value, bool),
        float: _is_number(value) and math.isfinite(value),
        str: isinstance(value, str),
    }
    if hint in fits and not fits[hint]:
        return f"{name}={value!r} must be {describe_type(hint)}"
    if origin is tuple:
        if not isinstance(value, tuple | list):
            return f"{name}={value!r} must be a list"
        element_hints = [args[0]] * len(value) if args[-1] is Ellipsis else list(args)
        if len(element_hints) != len(value):
            return f"{name}={list(value)} must have {len(element_hints)} values"
        for i, (element_hint, element) in enumerate(zip(element_hints, value, strict=True)):
            found = _type_problem(f"{name}[{i}]", element_hint, element)
            if found:
                return found
    if origin is dict and not isinstance(value, dict):
        return f"{name}={value!r} must be {describe_type(hint)}"
    return None


def type_problems(config: Any, prefix: str = "") -> list[str]:
    """One line per field of ``config`` whose value does not have its annotated type or is not
    finite (names start with ``prefix``, e.g. ``"collector."`` for a group alone)."""
    return [
        problem
        for name, _, hint in _leaves(type(config), prefix)
        if (problem := _type_problem(name, hint, get(config, name.removeprefix(prefix))))
    ]


def declared_problems(config: Any, prefix: str = "") -> list[str]:
    """One line per field of ``config`` outside its declared choices or range (values of the
    right type: :func:`type_problems` first)."""
    problems = []
    for name, f, hint in _leaves(type(config), prefix):
        value = get(config, name.removeprefix(prefix))
        valid = choices_of(f)
        if valid is not None and value not in valid:
            problems.append(f"{name}={value!r} is not one of {valid}")
        bounds = f.metadata.get("bounds")
        if bounds is None or value is None:
            continue
        if isinstance(value, tuple | list):  # a list of sizes: each one
            if any(element not in bounds for element in value):
                problems.append(f"{name}={list(value)}: each value must be {bounds.describe()}")
        elif value not in bounds:
            nullable = type(None) in typing.get_args(hint)
            problems.append(
                f"{name}={value} must be {bounds.describe()}" + (" (or null)" if nullable else "")
            )
    return problems
