"""The ``gentlerl-train`` command line before and after hydra reads it: overrides refused up
front, and hydra's own errors as one line naming the field, the value and what is expected.

Refused before hydra runs: a key that names no config field, ``~field`` (the field would
silently take its default), hydra's run / sweep directories (the run's is ``run_dir``; hydra
would leave the folder it names empty), and a boolean written as a number or a word (OmegaConf
reads ``learner.compile=1``, ``0``, ``yes``, ``on`` as booleans) or a number written as a
boolean (``seed=true``) or with ``_`` (``1_000``: hydra reads 1000, sweep and suite files and
``--set``, YAML 1.2 core, a word), so that every command reads a value the same way.
"""

from __future__ import annotations

import re
import types
import typing
from collections.abc import Sequence
from typing import Any

from gentlerl.apps.errors import causes
from gentlerl.config.fields import describe_type, field_hints
from gentlerl.config.groups import GROUPS
from gentlerl.config.presets import SCALES
from gentlerl.training.config import TrainConfig

#: hydra's folders, which gentlerl sets from ``run_dir``.
HYDRA_DIRS = ("hydra.run.dir", "hydra.sweep.dir", "hydra.sweep.subdir")


def override_problems(overrides: Sequence[str]) -> list[str]:
    """One line per override of ``overrides`` (a ``gentlerl-train`` command line) refused before
    hydra reads it; hydra's other flags and ``hydra.*`` settings are left to hydra."""
    fields = field_hints(TrainConfig)
    plain = [
        a.partition("=")[0] for a in overrides if "=" in a and not a.startswith(("-", "+", "~"))
    ]
    unknown = [k for k in plain if k not in fields and not k.startswith("hydra.") and k != "hydra"]
    problems = []
    if unknown:
        problems.append(
            f"unknown config field(s) {unknown}: `gentlerl train --help` lists them (a task "
            "keyword goes in as +env.kwargs.NAME=VALUE)"
        )
    for item in overrides:
        key = item.partition("=")[0]
        if key.startswith("~") and (key[1:] in fields or key[1:] in GROUPS):
            problems.append(
                f"{item}: a config field cannot be removed (it would take its default without a "
                f"word); set it instead ({key[1:]}=...)"
            )
        elif key == "scale" and item.partition("=")[2].lstrip().startswith("["):
            # a config group: hydra would merge a list's presets ([cpu,paper]) one on another
            problems.append(f"{item}: scale is one preset of {sorted(SCALES)}")
        elif key.lstrip("+") in HYDRA_DIRS:
            problems.append(f"{item}: gentlerl sets hydra's folders from run_dir; set run_dir")
        elif "=" in item and (hint := fields.get(key.lstrip("+"))) is not None:
            if problem := _boolean_problem(item, hint):
                problems.append(problem)
    return problems


def _scalar_kinds(hint: Any) -> set[Any]:
    """The scalar types a field of annotation ``hint`` holds (its list's elements for a list)."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType, tuple):
        return {kind for arg in args if arg is not Ellipsis for kind in _scalar_kinds(arg)}
    return {hint}


def _boolean_problem(item: str, hint: Any) -> str | None:
    """Why the override ``item`` (``field=text``) mixes booleans and numbers, or ``None``: a
    boolean field takes only ``true`` / ``false`` (or ``null``), a number field no ``true`` /
    ``false``; other texts are hydra's to read."""
    text = item.partition("=")[2].strip()
    kinds = _scalar_kinds(hint)
    words = {w.strip().lower() for w in text.strip("[]").split(",")}
    if kinds <= {bool, type(None)}:
        allowed = {"true", "false"} | ({"null"} if type(None) in kinds else set())
        return None if text.lower() in allowed else f"{item} must be {describe_type(hint)}"
    if bool not in kinds and str not in kinds and words & {"true", "false"}:
        return f"{item} must be {describe_type(hint)}"
    if str not in kinds and kinds & {int, float} and any(_UNDERSCORED.fullmatch(w) for w in words):
        # hydra reads 1_000 as 1000; a sweep, suite or --set value (YAML 1.2 core) does not
        return f"{item}: write numbers without '_' (YAML 1.2 core, as sweep and suite files read)"
    return None


#: A number with ``_`` between its digits (``1_000``), which hydra's grammar reads and YAML 1.2
#: core does not.
_UNDERSCORED = re.compile(r"[-+]?[0-9][0-9_]*_[0-9_]*(?:\.[0-9_]*)?(?:[eE][-+]?[0-9_]+)?")


def hydra_error_line(err: BaseException, overrides: Sequence[str]) -> str:
    """hydra's error ``err`` (composing the config of ``overrides``, or resolving it) as one line:
    ``field=value must be <type>`` for a value of the wrong type, the override and hydra's reason
    for anything else."""
    hints = field_hints(TrainConfig)
    given = {a.partition("=")[0].lstrip("+"): a for a in overrides if "=" in a}
    for cause in causes(err):
        field = re.sub(r"\[\d+\]$", "", str(getattr(cause, "full_key", "") or ""))
        if field not in hints:
            continue
        item = given.get(field, f"{field}=...")
        if type(cause).__name__ == "ValidationError":
            return f"{item} must be {describe_type(hints[field])}"
        return f"{item}: {_first_line(cause)}"
    bad = next((getattr(e, "override", None) for e in causes(err) if hasattr(e, "override")), None)
    if bad is None:
        return _first_line(err)
    key, _, value = bad.partition("=")
    return f"{bad}: {_first_line(err)} (a value hydra's grammar cannot read; a string: {key}='{value}')"


def _first_line(err: BaseException) -> str:
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    return lines[0] if lines else type(err).__name__
