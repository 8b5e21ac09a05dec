"""Every docstring example in ``src/gentlerl`` runs and prints what it shows (``doctest``).

The modules are found by their text (a ``>>>`` line), so an example added to any module is run
without a list to update; each module is imported only here, not at collection.
"""

import doctest
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "gentlerl"


def _modules_with_examples() -> list[str]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if any(line.lstrip().startswith(">>>") for line in path.read_text().splitlines()):
            parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
            found.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return found


MODULES = _modules_with_examples()


def test_the_examples_are_found():
    # The modules known to hold examples (a path mistake would silently run none).
    known = {"gentlerl.transforms.impact", "gentlerl.transforms.wear", "gentlerl.rewards.sum",
             "gentlerl.objectives.d4pg"}  # fmt: skip
    assert known <= set(MODULES), f"missing: {known - set(MODULES)}"


@pytest.mark.parametrize("name", MODULES)
def test_the_docstring_examples_run(name):
    result = doctest.testmod(importlib.import_module(name), verbose=False, report=True)
    assert result.attempted > 0, f"{name} has '>>>' lines that doctest did not find"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed"
