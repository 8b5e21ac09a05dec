"""Reading a suite file: a benchmark's tasks x variants x seeds at a budget, in one YAML file.

::

    suite: after_fix                   # its rows' name in results.csv (default: the file's stem)
    seeds: [0, 1, 2]                   # every cell's seeds, trained as one seed group
    set: [logging.progress=false]      # FIELD=VALUE settings of every cell, as --set takes them
    tasks:                             # a task's label -> its settings (env, budget, tolerance)
      touch: [task=touch, collector.total_frames=30000]
      finger-spin: [env.name=dm_control:finger-spin, collector.total_frames=50000]
    variants:                          # a variant's label -> its settings
      r: [variant=r]
      constrained: [variant=r+rf, gentleness.multiplier=pid, gentleness.multiplier_base=0.0]
    cells:                             # optional: the (task, variant) pairs to run, each with
      - {task: touch, variant: r}      # settings of its own (set: [...]); default: every pair

A cell is a task and a variant (``touch/r``): its settings are the suite's, then the task's, the
variant's and its own (a later one wins), each item held to ``--set``'s rules
(:func:`~gentlerl.apps.sweep_files.parse_set`: config fields only, plain values, no Ray
collector); ``seed``, ``run_dir`` and ``resume`` are the runner's. Labels name folders, so they
are plain names. Whether each cell's settings make a valid config is checked by the runner
(:mod:`gentlerl.apps.suite`), every cell before any runs.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from gentlerl.apps.sweep_files import parse_set
from gentlerl.config.limits import MAX_SEEDS
from gentlerl.files import load_yaml_file

#: A suite's, task's or variant's label: a folder name (no '/', no leading '.').
LABEL = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,99}")
#: Settings the runner sets per seed.
PER_SEED = ("seed", "run_dir", "resume")
#: The keys a suite file may hold.
KEYS = ("suite", "seeds", "set", "tasks", "variants", "cells")
#: The most cells a suite may have.
MAX_CELLS = 1_000


@dataclass(frozen=True)
class Cell:
    """One task and one variant of a suite: its settings (``FIELD=VALUE`` items, in order)."""

    task: str
    variant: str
    items: tuple[str, ...]

    @property
    def name(self) -> str:
        """``task/variant``: the cell's folder under the suite's ``--out`` and its CSV name."""
        return f"{self.task}/{self.variant}"


@dataclass(frozen=True)
class Suite:
    """A suite file's name, seeds and cells (in the file's order)."""

    name: str
    seeds: tuple[int, ...]
    cells: tuple[Cell, ...]


def _items(value: Any, where: str) -> tuple[str, ...]:
    """A list of ``FIELD=VALUE`` settings, each checked as ``--set`` checks it."""
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ValueError(f"{where}: expected a list of FIELD=VALUE strings, got {value!r:.80}")
    for item in value:
        if (key := item.partition("=")[0].lstrip("+")) in PER_SEED:
            raise ValueError(f"{where}: {item!r}: {key} is set per seed by the suite's runner")
    try:
        parse_set(value)
    except ValueError as err:
        raise ValueError(f"{where}: {err}") from None
    return tuple(value)


def _label(value: Any, where: str) -> str:
    if not isinstance(value, str) or not LABEL.fullmatch(value):
        raise ValueError(
            f"{where}: {value!r:.80} is not a label (letters, digits and '_.+-', not first; at "
            "most 100): labels name folders"
        )
    return value


def _labelled(spec: dict, key: str, path: Path) -> dict[str, tuple[str, ...]]:
    """``tasks:`` or ``variants:``: label -> its settings."""
    table = spec.get(key)
    if not isinstance(table, dict) or not table:
        raise ValueError(f"{path}: `{key}:` must be a non-empty mapping of label -> [FIELD=VALUE]")
    return {
        _label(label, f"{path}: {key}"): _items(items, f"{path}: {key}.{label}")
        for label, items in table.items()
    }


def _seeds(value: Any, path: Path) -> tuple[int, ...]:
    if (
        not isinstance(value, list)
        or not value
        or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value)
    ):
        raise ValueError(f"{path}: `seeds:` must be a list of integers >= 0, got {value!r:.80}")
    if len(set(value)) != len(value) or len(value) > MAX_SEEDS:
        raise ValueError(f"{path}: `seeds:` must be different, at most {MAX_SEEDS}, got {value}")
    return tuple(value)


def _cells(spec: dict, tasks: dict, variants: dict, common: tuple, path: Path) -> list[Cell]:
    """The cells ``cells:`` lists, or every task x variant pair (tasks outer)."""
    listed = spec.get("cells")
    if listed is None:
        listed = [{"task": t, "variant": v} for t in tasks for v in variants]
    if not isinstance(listed, list) or not listed or len(listed) > MAX_CELLS:
        raise ValueError(f"{path}: `cells:` must be a list of 1 to {MAX_CELLS} cells")
    cells: list[Cell] = []
    for i, entry in enumerate(listed):
        where = f"{path}: cells[{i}]"
        if not isinstance(entry, dict) or set(entry) - {"task", "variant", "set"}:
            raise ValueError(f"{where}: expected {{task: T, variant: V, set: [...]}}")
        task, variant = entry.get("task"), entry.get("variant")
        if task not in tasks or variant not in variants:
            raise ValueError(
                f"{where}: task {task!r} / variant {variant!r}: not both declared (tasks: "
                f"{list(tasks)}, variants: {list(variants)})"
            )
        own = _items(entry.get("set"), f"{where}.set")
        cell = Cell(task, variant, (*common, *tasks[task], *variants[variant], *own))
        if any(c.name == cell.name for c in cells):
            raise ValueError(f"{where}: cell {cell.name} is listed twice")
        cells.append(cell)
    return cells


def load_suite(path: str | Path) -> Suite:
    """The suite file at ``path``, every key, label and setting checked (a ``ValueError`` naming
    the file and what is wrong, in one line)."""
    path = Path(path)
    try:
        spec = load_yaml_file(path)
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    if not isinstance(spec, dict):
        raise ValueError(f"{path}: expected a mapping with tasks:, variants: and seeds:")
    unknown = [str(k) for k in spec if k not in KEYS]
    if unknown:
        raise ValueError(f"{path}: unknown keys {unknown}; a suite file holds {list(KEYS)}")
    name = _label(spec.get("suite", path.stem), f"{path}: suite")
    seeds = _seeds(spec.get("seeds"), path)
    common = _items(spec.get("set"), f"{path}: set")
    tasks = _labelled(spec, "tasks", path)
    variants = _labelled(spec, "variants", path)
    return Suite(name, seeds, tuple(_cells(spec, tasks, variants, common, path)))
