"""The tests mirror the package: each module ``gentlerl/<package>/<module>.py`` has a test file in
``tests/<package>/`` that imports it (``import gentlerl.<package>.<module>``, ``from
gentlerl.<package>.<module> import ...``, or ``from gentlerl.<package> import <name>`` of a name
the module defines). A file's name or docstring mentioning the module does not count: only an
import shows that the file runs its code. A top-level module's folder is ``tests/`` (and
``tests/repo/``); ``tests/experiments/`` tests the checkout's ``experiments/``. The modules
without such a test when the tests were laid out this way are listed in :data:`WITHOUT_A_TEST`;
the list only shrinks.

An imported name that cannot be resolved (the import raises) fails the test, naming the file:
an error swallowed here would count a broken import as "no module" instead of showing it.
"""

import ast
import functools
import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "gentlerl"
TESTS = ROOT / "tests"

#: Modules tested only through others (or in another package's folder), each awaiting a test of
#: its own in its folder. A new module comes with its test rather than a line here.
WITHOUT_A_TEST = {
    "gentlerl.apps.closing",  # the run's closing lines: tests/repo/test_clean_console.py
    "gentlerl.apps.outputs",
    "gentlerl.apps.parsing",
    "gentlerl.config.layout",  # RunLayout: tests/training/test_builders.py, test_logging.py
    "gentlerl.config.presets",  # SCALES: tests/config/test_config.py through make_config
    "gentlerl.envs.environment",
    "gentlerl.envs.rendering",
    "gentlerl.envs.task_names",
    "gentlerl.models.layers",
    "gentlerl.training.env_probe",
    "gentlerl.training.migration",  # old checkpoints' configs: tests/config/test_config.py
    "gentlerl.training.policy_weights",
    "gentlerl.training.seeding",
    "gentlerl.training.state_checks",
}


@functools.cache
def _modules() -> dict[str, Path]:
    """Dotted name -> the test folder that mirrors it, for every module but ``__init__`` /
    ``__main__``."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.name not in ("__init__.py", "__main__.py"):
            found["gentlerl." + ".".join(rel.with_suffix("").parts)] = TESTS / rel.parent
    return found


def _module_of(package: str, name: str, path: Path) -> set[str]:
    """The module that defines ``package.name`` (a submodule itself, or where a class or function
    was defined). An import error is raised, naming the test file ``path`` that imports it."""
    try:
        owner = importlib.import_module(package)
        # as ``from package import name`` does: an attribute, else a submodule of that name
        if hasattr(owner, name):
            value = getattr(owner, name)
        else:
            value = importlib.import_module(f"{package}.{name}")
    except Exception as err:
        raise AssertionError(
            f"{path.relative_to(ROOT)}: from {package} import {name} fails here: {err!r}"
        ) from err
    if isinstance(value, type(sys)):
        return {value.__name__}
    return {getattr(value, "__module__", None) or package}


def _imported(path: Path) -> set[str]:
    """The gentlerl modules a test file imports, and the modules defining the names it imports.

    A file that calls ``importlib.import_module`` imports the modules whose full names it writes
    as strings (``"gentlerl.analysis.method3"``): a module that only refuses to be imported is
    tested that way.
    """
    out: set[str] = set()
    tree = ast.parse(path.read_text())
    dynamic = any(
        isinstance(node, ast.Attribute) and node.attr == "import_module" for node in ast.walk(tree)
    )
    for node in ast.walk(tree):
        if dynamic and isinstance(node, ast.Constant) and isinstance(node.value, str):
            if node.value.startswith("gentlerl.") and node.value in _modules():
                out.add(node.value)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("gentlerl")}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("gentlerl"):
            out.add(node.module)
            for alias in node.names:
                out |= _module_of(node.module, alias.name, path)
    return out


def _tested(module: str, folder: Path) -> bool:
    files = sorted(folder.glob("test_*.py"))
    if folder == TESTS:
        files += sorted((TESTS / "repo").glob("test_*.py"))
    return any(module in _imported(f) for f in files)


def test_every_module_has_a_test_in_the_folder_that_mirrors_it():
    modules = _modules()
    assert len(modules) > 60  # the package, not a wrong path
    untested = {m for m, folder in modules.items() if not _tested(m, folder)}
    new = sorted(untested - WITHOUT_A_TEST)
    assert not new, f"modules without a test in their tests/<package>/ folder: {new}"
    gone = sorted(WITHOUT_A_TEST - set(modules))
    assert not gone, f"WITHOUT_A_TEST names modules the package no longer has: {gone}"
    tested_now = sorted(WITHOUT_A_TEST - untested)
    assert not tested_now, f"these have a test now: take them off WITHOUT_A_TEST: {tested_now}"


def test_every_test_folder_mirrors_a_package():
    folders = {p.name for p in TESTS.iterdir() if (p / "__init__.py").exists()}
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    # repo: the checkout's files; experiments: the checkout's experiments/, not a package of gentlerl
    extra = folders - packages
    assert extra == {"repo", "experiments"}, f"test folders with no package: {extra}"
    assert not packages - folders, f"packages with no test folder: {packages - folders}"
    stray = [p.name for p in TESTS.glob("test_*.py")
             if not (PACKAGE / f"{p.stem.removeprefix('test_').split('_')[0]}.py").exists()]  # fmt: skip
    assert not stray, f"top-level test files that mirror no top-level module: {stray}"
