"""benchmarks/mutation.py's ``--rerun``: it tests again only the mutants the last run did not
kill, so it must refuse where the earlier verdicts no longer describe the source. No mutmut run
here (its statuses are given); the runs themselves are the benchmark."""

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def mutation(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("mutation", ROOT / "benchmarks" / "mutation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    tree = tmp_path / "tree"
    (tree / "src" / "gentlerl" / "rewards").mkdir(parents=True)
    (tree / "src" / "gentlerl" / "rewards" / "sum.py").write_text("x = 1\n")
    (tree / "tests").mkdir()
    (tree / "tests" / "test_new.py").write_text("def test_new(): pass\n")
    monkeypatch.setattr(module, "ROOT", tree)
    statuses = {"m__mutmut_1": "killed", "m__mutmut_2": "survived", "m__mutmut_3": "no tests"}
    monkeypatch.setattr(module, "statuses", lambda workdir: statuses)
    return module


def _earlier_run(tree: Path, workdir: Path) -> None:
    """A work folder as ``prepare`` and a mutmut run leave it: the source copied, ``mutants/``."""
    (workdir / "src" / "gentlerl" / "rewards").mkdir(parents=True)
    source = "src/gentlerl/rewards/sum.py"
    (workdir / source).write_bytes((tree / source).read_bytes())
    (workdir / "tests").mkdir()
    (workdir / "tests" / "test_old.py").write_text("def test_old(): pass\n")
    (workdir / "mutants").mkdir()
    (workdir / ".gentlerl-mutation-workdir").write_text("made by benchmarks/mutation.py\n")


def test_a_rerun_copies_the_tests_again_and_names_the_mutants_not_killed(mutation, tmp_path):
    workdir = tmp_path / "work"
    _earlier_run(mutation.ROOT, workdir)
    assert mutation.tests_again(workdir) == ["m__mutmut_2", "m__mutmut_3"]
    assert sorted(p.name for p in (workdir / "tests").iterdir()) == ["test_new.py"]


def test_a_rerun_refuses_without_an_earlier_run(mutation, tmp_path):
    with pytest.raises(SystemExit, match="no earlier run in .*run without --rerun first"):
        mutation.tests_again(tmp_path / "work")


@pytest.mark.parametrize("change", ["edited", "added"])
def test_a_rerun_refuses_when_the_source_changed_since_the_mutants_were_made(
    mutation, tmp_path, change
):
    workdir = tmp_path / "work"
    _earlier_run(mutation.ROOT, workdir)
    name = "sum.py" if change == "edited" else "extra.py"
    (mutation.ROOT / "src" / "gentlerl" / "rewards" / name).write_text("x = 2\n")
    with pytest.raises(SystemExit, match=f"the source changed .*rewards/{name}"):
        mutation.tests_again(workdir)
    assert (workdir / "tests" / "test_old.py").exists()  # nothing was copied


def test_a_rerun_refuses_a_folder_it_did_not_make_and_deletes_nothing(mutation, tmp_path):
    """The finding: ``--rerun --workdir DIR`` with a ``mutants/`` folder deleted ``DIR/tests``."""
    workdir = tmp_path / "work"
    _earlier_run(mutation.ROOT, workdir)
    (workdir / ".gentlerl-mutation-workdir").unlink()
    with pytest.raises(SystemExit, match="did not make .*it deletes only its own work folders"):
        mutation.tests_again(workdir)
    assert (workdir / "tests" / "test_old.py").exists()


@pytest.mark.parametrize("where", [".", "src", "tests", "src/gentlerl", "..", "other", "link"])
def test_a_workdir_it_did_not_make_is_refused_and_nothing_is_deleted(mutation, tmp_path, where):
    """The finding: ``--workdir .`` deleted a checkout copy, ``--workdir src`` the package."""
    tree = mutation.ROOT
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "precious.txt").write_text("keep\n")
    (tree / "link").symlink_to(tmp_path / "other")
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    with pytest.raises(SystemExit, match=r"--workdir .*(did not make|checkout|link or a file)"):
        mutation.prepare("rewards", (tmp_path / where) if where == "other" else tree / where)
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_its_own_work_folder_is_replaced_and_an_empty_one_taken(mutation, tmp_path):
    (mutation.ROOT / "pyproject.toml").write_text("[tool.pytest.ini_options]\n")
    workdir = tmp_path / "work"
    workdir.mkdir()
    mutation.prepare("rewards", workdir)  # empty: taken and marked
    (workdir / "stale.txt").write_text("from the last run\n")
    mutation.prepare("rewards", workdir)  # marked: replaced
    assert not (workdir / "stale.txt").exists()
    assert (workdir / ".gentlerl-mutation-workdir").is_file()
    assert (workdir / "src" / "gentlerl" / "rewards" / "sum.py").exists()
