"""CONTRIBUTING.md's layout and "where does my change go" tables name what the tree holds."""

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "gentlerl"
TEXT = (ROOT / "CONTRIBUTING.md").read_text()


def _section(title: str) -> str:
    start = TEXT.index(f"## {title}")
    end = TEXT.find("\n## ", start + 1)
    return TEXT[start:end]


def _code_spans(text: str) -> list[str]:
    return re.findall(r"`([^`\s]+)`", text)


def test_every_module_and_package_the_tables_name_exists() -> None:
    tables = _section("Layout") + _section("Where does my change go")
    named = [s for s in _code_spans(tables) if s.endswith((".py", "/")) and "<" not in s]
    assert len(named) > 40  # the tables name the tree, not a handful of files
    top = ("recipes/", "experiments/", "benchmarks/", "docs/", "tests/")
    missing = []
    for span in named:
        if span.startswith(top):
            found = (ROOT / span).exists()
        else:  # a package path (``config/groups.py``), a recipes or experiments file, or a bare module
            found = (
                (PACKAGE / span).exists()
                or (ROOT / "recipes" / span).exists()
                or (ROOT / "experiments" / span).exists()
                or any(PACKAGE.rglob(Path(span).name))
            )
        if not found:
            missing.append(span)
    assert not missing, f"CONTRIBUTING.md names {missing}, which the tree does not hold"


def test_the_layout_table_lists_every_package_of_the_tree() -> None:
    table = _section("Layout")
    packages = sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists())
    unlisted = [p for p in packages if f"`{p}/`" not in table]
    assert not unlisted, f"packages missing from CONTRIBUTING.md's layout table: {unlisted}"


def test_the_names_the_change_table_points_to_are_defined_there() -> None:
    # name -> module the "where does my change go" table says holds it
    places = {
        "setting": "gentlerl.config.fields",
        "RunLayout": "gentlerl.config.layout",
        "SCALES": "gentlerl.config.presets",
        "COLLECTORS": "gentlerl.config.groups",
        "TASK_CLASSES": "gentlerl.envs.factory",
        "FORCE_ADAPTERS": "gentlerl.envs.external",
        "COMPONENTS": "gentlerl.rewards.variants",
        "VARIANTS": "gentlerl.rewards.variants",
        "make_collector": "gentlerl.training.builders",
        "_BEFORE": "gentlerl.training.migration",
        "command_parser": "gentlerl.apps.parsing",
        "COMMANDS": "gentlerl.cli",
        "ray_problems": "gentlerl.distributed.collector",
    }
    table = _section("Where does my change go") + _section("Layout")
    for name, module in places.items():
        assert f"`{name}" in table, f"{name} is no longer named in CONTRIBUTING.md"
        assert hasattr(importlib.import_module(module), name), f"{module} has no {name}"
