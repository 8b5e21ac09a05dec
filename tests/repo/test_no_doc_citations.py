"""The library cites none of the checkout's documents: a docstring, comment or message in
``src/`` that sends the reader to ``docs/*.md``, ``benchmarks/RESULTS.md``, the README or another
markdown file of the repository fails here. An installed library has no such files beside it; a
measured number that explains a design choice is stated as such, without the citation. Neither
``src/`` nor ``tests/`` cite the research log (``docs/log/``, the amendment history): what the
code and tests hold true does not rest on it.
"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "gentlerl"

#: Files allowed to cite a document: none. A file that cites one fails the first test.
ALLOWED: set[str] = set()


def _documents(root: Path) -> set[str]:
    """The names of the repository's written documents: the markdown files at the top and directly
    in ``docs/``, ``docs/log/``, ``benchmarks/``, ``experiments/`` (not the ``summary.md`` / ``claims.md`` tables
    that runs write and ``docs/figures/`` keeps)."""
    found = set(root.glob("*.md"))
    for folder in ("docs", "docs/log", "benchmarks", "experiments"):
        found |= set((root / folder).glob("*.md"))
    return {path.name for path in found}


def citation_pattern(documents: set[str]) -> re.Pattern[str]:
    """A path into ``docs/`` naming a markdown file (existing or not), or any of ``documents``
    (with or without its folder); not an output file the code writes (``summary.md``), a
    placeholder (``OUT.md``) or a folder such as ``docs/policies``."""
    names = "|".join(sorted(map(re.escape, documents))) or r"(?!)"
    return re.compile(rf"(?<![\w.-])(?:docs/[\w./-]*\.md|(?:[\w.-]+/)*(?:{names}))(?![\w-])")


def citations(src: Path, pattern: re.Pattern[str]) -> dict[str, list[str]]:
    """Path under ``src`` -> its lines that cite a document, as ``line: text``."""
    out: dict[str, list[str]] = {}
    for path in sorted(src.rglob("*.py")):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if pattern.search(line):
                out.setdefault(path.relative_to(src).as_posix(), []).append(f"{number}: {line}")
    return out


PATTERN = citation_pattern(_documents(ROOT))


def test_the_documents_are_found():
    assert {"README.md", "CONTRIBUTING.md", "RESULTS.md", "REPRODUCTION.md"} <= _documents(ROOT)


@pytest.mark.parametrize(
    "line",
    [
        "see docs/REGIMES.md",
        "(measured, docs/FUTURE_NOTES.md)",
        "6 % of a run, benchmarks/RESULTS.md).",
        "CONTRIBUTING.md maps the paper's names",
        "REPRODUCTION.md's criteria",
        "``README.md``",
    ],
)
def test_a_citation_is_found(line):
    assert PATTERN.search(line), line


@pytest.mark.parametrize(
    "line",
    [
        "``summary.csv`` / ``summary.md``",
        "[--markdown OUT.md]",
        '"--out", default="docs/policies"',
        "python experiments/method3/table.py RUNS_DIR",
        "GENTLEBENCH_R_LEARNS = 20.0",
        "MY_README.md.bak",
    ],
)
def test_what_is_not_a_citation_is_not_found(line):
    assert not PATTERN.search(line), line


def test_a_planted_citation_in_a_source_tree_is_reported(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "clean.py").write_text('"""The summary writes summary.md."""\n')
    (tmp_path / "pkg" / "cites.py").write_text("x = 1\n# measured (docs/log/REPRODUCTION.md)\n")
    assert citations(tmp_path, PATTERN) == {
        "pkg/cites.py": ["2: # measured (docs/log/REPRODUCTION.md)"]
    }


def test_src_cites_no_document_but_the_allowed_files():
    found = citations(SRC, PATTERN)
    cited = {path: lines for path, lines in found.items() if path not in ALLOWED}
    assert not cited, f"src/ cites the checkout's documents: {cited}"


def test_every_allowed_file_still_cites():
    gone = sorted(ALLOWED - set(citations(SRC, PATTERN)))
    assert not gone, f"these cite no document now: take them off ALLOWED: {gone}"


#: The research log's documents.
LOG = ROOT / "docs" / "log"


def test_no_library_or_test_file_cites_the_research_log():
    assert {"REPRODUCTION.md", "GENTLEBENCH.md", "SAC.md", "FINGER.md"} <= {
        p.name for p in LOG.glob("*.md")
    }
    names = "|".join(re.escape(p.name) for p in LOG.glob("*.md") if p.name != "README.md")
    log = re.compile(rf"(?<![\w.-])(?:[\w.-]+/)*(?:{names})(?![\w-])")
    this = Path(__file__).resolve()
    found = {
        f"{path.relative_to(ROOT)}:{number}"
        for folder in (SRC, ROOT / "tests")
        for path in sorted(folder.rglob("*.py"))
        if path.resolve() != this
        for number, line in enumerate(path.read_text().splitlines(), 1)
        if "docs/log/" in line or log.search(line)
    }
    assert not found, f"these cite the research log: {sorted(found)}"
