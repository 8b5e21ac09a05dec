"""benchmarks/hostile.py (issue 55's findings re-run against a tree): every probe names a test
that exists, every finding has a probe, and its classification of a refusal. Nothing is probed
here (no subprocess): the probes themselves run in the benchmark."""

import ast
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def hostile():
    spec = importlib.util.spec_from_file_location("hostile", ROOT / "benchmarks" / "hostile.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["hostile"] = module  # dataclasses look their module up
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.modules.pop("hostile", None)


def _test_functions(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    return {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}


def test_every_probe_names_a_test_that_exists(hostile):
    for probe in hostile.PROBES:
        file, _, name = probe.test.partition("::")
        path = ROOT / file
        assert file.startswith("tests/") and path.is_file(), (probe.name, file)
        assert name.startswith("test_") and name in _test_functions(path), (probe.name, name)


def test_every_finding_of_issue_55_has_a_probe_and_every_probe_a_run(hostile):
    names = [p.name for p in hostile.PROBES]
    assert len(set(names)) == len(names)
    findings = {p.finding.split(":", 1)[0] for p in hostile.PROBES}
    assert findings == {str(n) for n in range(1, 11)}
    assert set(hostile.CHILDREN) <= set(names)
    assert all(callable(p.run) for p in hostile.PROBES)
    assert set(hostile.BAD) <= set(hostile.CLASSES) and hostile.NA in hostile.CLASSES


def test_a_refusal_is_one_clear_line_that_left_nothing(hostile):
    assert hostile.refusal(ValueError("seed=-1 must be >= 0"), clean=True)[0] == "refused"
    assert hostile.refusal(SystemExit("gentlerl train: error: x"), clean=True)[0] == "refused"
    assert hostile.refusal(ValueError("x must be >= 0"), clean=False)[0] == "late refusal"
    assert hostile.refusal(RuntimeError("CUDA error"), clean=True)[0] == "traceback"
    assert hostile.refusal(ValueError("a\nb"), clean=True)[0] == "traceback"
    assert hostile.refusal(ValueError(""), clean=True)[0] == "traceback"


def test_the_table_counts_every_class(hostile):
    probe = hostile.PROBES[0]
    rows = [(probe, "refused", "a | b", 1.0), (probe, "lost", "x", 2.0)]
    lines = hostile.table(rows)
    assert lines[2].startswith(f"| `{probe.name}` |") and "a \\| b" in lines[2]
    counts = dict(
        line.strip("| ").split(" | ") for line in lines[lines.index("| class | probes |") + 2 :]
    )
    assert counts["refused"] == "1" and counts["lost"] == "1" and counts["hang"] == "0"
    assert set(counts) == set(hostile.CLASSES)
