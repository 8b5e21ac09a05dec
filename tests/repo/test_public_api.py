"""The public API (each package's ``__all__`` and its signatures) is the committed snapshot
``tests/repo/public_api.json`` (``tests/repo/api_snapshot.py``), and the version is pyproject's.

A removal or a signature change fails until the snapshot is regenerated with its CHANGELOG.md
entry; an addition passes with a warning until then.
"""

import copy
import importlib
import importlib.metadata
import json
import re
import warnings
from pathlib import Path

import pytest

from tests.repo import api_snapshot
from tests.repo.api_snapshot import REGENERATE, compare, describe, public_packages

ROOT = Path(__file__).resolve().parents[2]
CHANGELOG = ROOT / "CHANGELOG.md"


class PublicAPIAddition(UserWarning):
    """A public name that the snapshot does not hold yet."""


@pytest.fixture(scope="module")
def current():
    return api_snapshot.snapshot()


def test_every_package_declares_its_public_names():
    packages = public_packages()
    assert len(packages) > 10 and packages[0] == "gentlerl"
    for package in packages:
        module = importlib.import_module(package)
        assert isinstance(getattr(module, "__all__", None), list), f"{package} has no __all__"
        assert all(hasattr(module, name) for name in module.__all__), package


def test_the_public_api_is_the_snapshot(current):
    breaks, additions = compare(api_snapshot.load(), current)
    assert not breaks, (
        f"the public API changed ({len(breaks)}): {'; '.join(breaks)}. A deliberate change: "
        f"`{REGENERATE}`, with a CHANGELOG.md entry (and a deprecation shim for a moved name)"
    )
    if additions:
        warnings.warn(
            f"new public names, not in the snapshot yet ({REGENERATE}): {', '.join(additions)}",
            PublicAPIAddition,
            stacklevel=1,
        )


def test_the_snapshot_file_is_what_write_writes(current, tmp_path):
    """Sorted and one entry a line, so that a regenerated snapshot's diff reads."""
    path = tmp_path / "api.json"
    api_snapshot.write(api_snapshot.load(), path)
    assert path.read_text() == api_snapshot.SNAPSHOT.read_text()


def _planted(api: dict, edit) -> tuple[list[str], list[str]]:
    new = copy.deepcopy(api)
    edit(new)
    return compare(api, new)


def test_compare_reports_every_planted_break(current):
    def drop_name(api):
        del api["gentlerl.functional"]["impact"]

    def change_signature(api):
        api["gentlerl.functional"]["impact"]["signature"] = "(force)"

    def drop_method(api):
        del api["gentlerl.objectives"]["MultiHeadD4PGLoss"]["members"]["forward"]

    def change_kind(api):
        api["gentlerl.config"]["SCALES"] = {"kind": "data", "type": "list"}

    def drop_package(api):
        del api["gentlerl.models"]

    planted = {
        drop_name: "gentlerl.functional.impact: removed",
        change_signature: "gentlerl.functional.impact: signature",
        drop_method: "gentlerl.objectives.MultiHeadD4PGLoss.forward: removed",
        change_kind: "gentlerl.config.SCALES: type dict -> list",
        drop_package: "gentlerl.models: removed",
    }
    for edit, expected in planted.items():
        breaks, _ = _planted(current, edit)
        assert len(breaks) == 1 and breaks[0].startswith(expected), (edit.__name__, breaks)


def test_compare_allows_additions_and_reports_them(current):
    def add(api):
        api["gentlerl.functional"]["new_equation"] = {"kind": "function", "signature": "()"}
        api["gentlerl.objectives"]["MultiHeadD4PGLoss"]["members"]["new_method"] = "(self)"
        api["gentlerl.newpackage"] = {}

    breaks, additions = _planted(current, add)
    assert breaks == []
    assert additions == [
        "gentlerl.functional.new_equation",
        "gentlerl.objectives.MultiHeadD4PGLoss.new_method",
        "gentlerl.newpackage",
    ]
    assert compare(current, current) == ([], [])


def test_a_changed_default_or_parameter_is_a_break():
    """From the objects, not the file: ``describe`` sees a default, a keyword-only marker, a
    removed method, and leaves out object addresses (which change every run)."""
    marker = object()

    def before(force, lam1=2.0, *, key=marker):
        """An equation."""

    def after(force, lam1=3.0, *, key=marker):
        """The same with another default."""

    def reordered(force, *, lam1=2.0, key=marker):
        """lam1 keyword-only."""

    old = describe(before)
    assert "0x" not in old["signature"]
    assert describe(after) != old and describe(reordered) != old
    for changed in (after, reordered):
        breaks, _ = compare({"p": {"f": old}}, {"p": {"f": describe(changed)}})
        assert breaks == [f"p.f: signature {old['signature']} -> {describe(changed)['signature']}"]

    class Old:
        def kept(self, x):
            """Kept."""

        def gone(self):
            """Removed below."""

    class New:
        def kept(self, x):
            """Kept."""

    Old.__module__ = New.__module__ = "gentlerl.fake"  # members come from gentlerl's classes
    breaks, _ = compare({"p": {"C": describe(Old)}}, {"p": {"C": describe(New)}})
    assert breaks == ["p.C.gone: removed"]


def test_the_snapshot_leaves_out_the_moving_analysis_names():
    held = json.loads(api_snapshot.SNAPSHOT.read_text())
    text = json.dumps(held)
    assert not re.search(r"method3|grid_table|gentlebench|sac_verdict", text, re.IGNORECASE)


def test_the_version_is_pyprojects_and_the_changelogs_newest_release():
    import gentlerl

    pyproject = re.search(r'(?m)^version = "([^"]+)"', (ROOT / "pyproject.toml").read_text())
    assert pyproject is not None
    releases = re.findall(r"(?m)^## \[(\d[^\]]*)\] - \d{4}-\d{2}-\d{2}$", CHANGELOG.read_text())
    assert releases[0] == pyproject.group(1), "CHANGELOG.md's newest release is not pyproject's"
    installed = importlib.metadata.distribution("gentlerl")
    assert gentlerl.__version__ == installed.version
    origin = json.loads(installed.read_text("direct_url.json") or "{}").get("url")
    if origin != ROOT.as_uri():
        pytest.skip(f"gentlerl is installed from {origin}, not this checkout: pip install -e .")
    assert gentlerl.__version__ == pyproject.group(1)


#: Names that left the snapshot under a deprecation shim: old -> new, each readable (with a
#: DeprecationWarning) until gentlerl.deprecation.REMOVED_IN.
RENAMED = {
    "gentlerl.transforms.TouchCalibration": "gentlerl.transforms.TouchSensorMap",
}


def _resolve(dotted: str):
    package, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(package), name)


def test_every_snapshot_name_still_resolves_or_has_a_shim():
    """A name cannot vanish from the package behind the snapshot's back: each one the committed
    snapshot holds is still there (its methods and properties too), whatever the compare says,
    and each renamed one resolves through its shim to its new name."""
    held = api_snapshot.load()
    missing = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for package, names in held.items():
            module = importlib.import_module(package)
            for name, entry in names.items():
                if not hasattr(module, name):
                    missing.append(f"{package}.{name}")
                    continue
                for member, kind in entry.get("members", {}).items():
                    # an "attribute" may be an instance's only (a dataclass field's factory)
                    if kind != "attribute" and not hasattr(getattr(module, name), member):
                        missing.append(f"{package}.{name}.{member}")
        for old, new in RENAMED.items():
            if _resolve(old) is not _resolve(new):
                missing.append(f"{old} (shim for {new})")
    assert len(held) > 10 and not missing, f"snapshot names that no longer resolve: {missing}"


@pytest.mark.parametrize(("old", "new"), sorted(RENAMED.items()))
def test_a_renamed_name_warns_until_its_removal_release(old, new):
    from gentlerl.deprecation import REMOVED_IN, deprecation_message

    with pytest.warns(DeprecationWarning) as caught:
        _resolve(old)
    assert [str(w.message) for w in caught] == [deprecation_message(old, new)]
    assert REMOVED_IN == "0.3.0"
