"""Mutation score of a package against its tests (mutmut 3; a measurement, not part of CI).

Each mutant is one small change to the package's source (an operator flipped, a constant moved,
an argument dropped); a test suite that checks the equations' numbers fails on it ("killed"), one
that only checks that they run lets it pass ("survived"). The score is

    killed / (total - equivalent)

where *equivalent* counts the survivors listed in ``benchmarks/mutation_equivalent.md``: mutants
that compute the same function as the source, so that no test can kill them (each is listed with
its mutated line and the reason; a listed mutant whose line no longer matches is not counted).

The package's source and the tests are copied into a work folder (``.mutation/PACKAGE``, ignored
by git) with the mutmut settings written there, so nothing in the tree is changed and mutmut's
``mutants/`` copy stays out of it. mutmut runs one mutant at a time (``--max-children 1``) under
``nice -n 19``; for every mutant it runs only the tests that call the mutated function, ``-x``.

Run: ``python benchmarks/mutation.py functional [--note "before ..."] [--record] [--survivors]``
(``mutmut`` installed in the same environment: ``pip install mutmut``). With ``--record`` the
numbers, with the machine, its load, the date and the command, are appended to
``benchmarks/RESULTS.md``.

``--rerun`` keeps the work folder of the last run and tests again only the mutants it did not
kill, against the tests copied in afresh: after tests were *added*, the full run's score in a
fraction of its time. It refuses when the source (any file of ``src/``) differs from the copy
the mutants were made from; a mutant killed before stays killed only while the test that killed it is kept,
so a run after tests were changed or removed must be a full one.

The work folder is this script's own: it writes a marker file (:data:`MARKER`) when it creates
it, and empties or replaces only a folder holding that marker (a regular file, not a link) that
is neither the checkout nor holds it. ``--workdir .`` or ``--workdir src`` is refused, never
deleted; an empty folder that exists is taken (and marked).
"""

from __future__ import annotations

import argparse
import datetime
import filecmp
import importlib.metadata
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "RESULTS.md"
EQUIVALENT = ROOT / "benchmarks" / "mutation_equivalent.md"

#: package -> the tests that cover it (mutmut runs, per mutant, those of them that reach it).
PACKAGES = {
    "functional": "tests/functional",
    "rewards": "tests/rewards",
    "objectives": "tests/objectives",
    "transforms": "tests/transforms",
}

#: Tests left out of a package's run, and why.
DESELECT = {
    "objectives": [
        # ~50 s of torch.compile per run, paid again by each mutant that reaches it
        "tests/objectives/test_compile.py::test_compiled_update_gives_the_eager_losses_"
        "priorities_and_parameters",
        # passes once per process only: mutmut runs the tests several times in one process, and
        # monkeypatch's undo leaves torch._inductor.config.cpp without its `cxx` attribute
        "tests/objectives/test_compile.py::test_compile_falls_back_to_eager_with_the_reason",
    ],
    # ~30 s of torch.compile per run, as above
    "rewards": [
        "tests/rewards/test_model_step.py::test_the_compiled_step_gives_the_eager_losses_and_"
        "parameters"
    ],
}

#: pytest's arguments for every mutant: stop at the first failure, quiet, no cache writes.
PYTEST_ARGS = ["-x", "-q", "-p", "no:cacheprovider"]

#: The file this script writes into a work folder it creates; only a folder holding it is emptied.
MARKER = ".gentlerl-mutation-workdir"

#: The statuses ``mutmut results --all true`` prints, in the order of the table.
STATUSES = ("killed", "survived", "timeout", "no tests", "suspicious", "segfault", "skipped")


def prepare(package: str, workdir: Path) -> None:
    """A fresh work folder: ``src/``, ``tests/``, ``pyproject.toml`` (pytest's settings) and the
    mutmut settings in a ``setup.cfg`` of its own."""
    if own_workdir(workdir):
        shutil.rmtree(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / MARKER).write_text("made by benchmarks/mutation.py; the folder is emptied by it\n")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "src", workdir / "src", ignore=ignore)
    shutil.copytree(ROOT / "tests", workdir / "tests", ignore=ignore)
    shutil.copy2(ROOT / "pyproject.toml", workdir / "pyproject.toml")
    lines = [
        "[mutmut]",
        "source_paths = src",
        f"only_mutate = src/gentlerl/{package}/*",
        "pytest_add_cli_args =",
        *(f"    {a}" for a in PYTEST_ARGS),
        "pytest_add_cli_args_test_selection =",
        f"    {PACKAGES[package]}",
        *(f"    --deselect={test}" for test in DESELECT.get(package, [])),
    ]
    (workdir / "setup.cfg").write_text("\n".join(lines) + "\n")


def own_workdir(workdir: Path) -> bool:
    """Whether ``workdir`` is a work folder this script made (it holds :data:`MARKER`, and may be
    emptied); ``False`` when it does not exist or is an empty folder; exits, deleting nothing,
    for anything else: a link, a file, the checkout or a folder holding it, a folder of files
    this script did not make."""
    if workdir.is_symlink() or (workdir.exists() and not workdir.is_dir()):
        sys.exit(f"--workdir {workdir}: not a folder (a link or a file); give a new folder")
    real, root = workdir.resolve(), ROOT.resolve()
    if root.is_relative_to(real) or any(real.is_relative_to(root / d) for d in ("src", "tests")):
        sys.exit(
            f"--workdir {workdir}: the checkout, a folder holding it, or inside its src/ or tests/"
            "; give a new folder"
        )
    if not workdir.exists():
        return False
    marker = workdir / MARKER
    if marker.is_file() and not marker.is_symlink():
        return True
    if any(workdir.iterdir()):
        sys.exit(
            f"--workdir {workdir}: a folder benchmarks/mutation.py did not make (no {MARKER}); "
            "it deletes only its own work folders: give a new or empty folder"
        )
    return False


def tests_again(workdir: Path) -> list[str]:
    """The mutants the last run in ``workdir`` did not kill, with the tests copied in again;
    exits when there was no run there or the source (any of ``src/``) changed since."""
    if not (workdir / "mutants").is_dir():
        sys.exit(f"--rerun: no earlier run in {workdir}; run without --rerun first")
    if not own_workdir(workdir):
        sys.exit(f"--rerun: {workdir} is not a work folder this script made; run without --rerun")
    if (workdir / "tests").is_symlink():
        sys.exit(f"--rerun: {workdir / 'tests'} is a link; run without --rerun")
    rel = [p.relative_to(ROOT) for p in sorted((ROOT / "src").rglob("*.py"))]
    changed = [
        str(r)
        for r in rel
        if not (workdir / r).exists() or not filecmp.cmp(ROOT / r, workdir / r, shallow=False)
    ]
    if changed:
        sys.exit(f"--rerun: the source changed since the mutants were made ({changed}); run again")
    shutil.rmtree(workdir / "tests")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "tests", workdir / "tests", ignore=ignore)
    return sorted(name for name, status in statuses(workdir).items() if status != "killed")


def mutmut(workdir: Path, *args: str, log: Path | None = None) -> str:
    """``mutmut ARGS`` in ``workdir`` (the source under test is the copy there, not ours)."""
    exe = Path(sys.executable).parent / "mutmut"
    command = [str(exe) if exe.exists() else "mutmut", *args]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if log is None:
        done = subprocess.run(command, cwd=workdir, env=env, capture_output=True, text=True)
        if done.returncode:
            sys.exit(f"mutmut {' '.join(args)} failed:\n{done.stdout}\n{done.stderr}")
        return done.stdout
    with log.open("w") as f:
        code = subprocess.run(
            ["nice", "-n", "19", *command], cwd=workdir, env=env, stdout=f, stderr=subprocess.STDOUT
        ).returncode
    if code:
        sys.exit(f"mutmut {' '.join(args)} failed ({code}); see {log}")
    return ""


def statuses(workdir: Path) -> dict[str, str]:
    """mutant name -> status, for every mutant."""
    out = mutmut(workdir, "results", "--all", "true")
    found = re.findall(r"^\s*(\S+): (.+)$", out, flags=re.MULTILINE)
    return {name: status.strip() for name, status in found}


def mutated_line(workdir: Path, name: str) -> str:
    """The mutant's changed line, as ``mutmut show`` gives it (its first ``+`` line, stripped)."""
    diff = mutmut(workdir, "show", name)
    added = [ln[1:].strip() for ln in diff.splitlines() if ln.startswith("+") and ln[1:].strip()]
    added = [ln for ln in added if not ln.startswith("++")]
    return added[0] if added else ""


def listed_equivalents() -> dict[str, str]:
    """mutant name -> its mutated line, from the table rows of ``mutation_equivalent.md``."""
    if not EQUIVALENT.exists():
        return {}
    rows = re.findall(r"^\| `([\w.]+__mutmut_\d+)` \| `(.+?)` \|", EQUIVALENT.read_text(), re.M)
    return dict(rows)


def machine() -> tuple[str, str, str]:
    """``nproc``, the CPU model (``/proc/cpuinfo``) and ``uptime``."""
    nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    model = "unknown"
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    return nproc, model, uptime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("package", choices=sorted(PACKAGES))
    parser.add_argument("--workdir", type=Path, help="default: .mutation/PACKAGE in the repo")
    parser.add_argument("--note", default="", help="a line for the record, e.g. 'before tests'")
    parser.add_argument("--record", action="store_true", help=f"append the numbers to {RESULTS}")
    parser.add_argument("--survivors", action="store_true", help="print each survivor's diff")
    parser.add_argument(
        "--rerun",
        action="store_true",
        help="test again only the mutants the last run in the work folder did not kill",
    )
    args = parser.parse_args()
    workdir = (args.workdir or ROOT / ".mutation" / args.package).resolve()
    command = "python benchmarks/mutation.py " + shlex.join(sys.argv[1:])

    try:
        version = importlib.metadata.version("mutmut")
    except importlib.metadata.PackageNotFoundError:
        sys.exit("mutmut is not installed in this environment: pip install mutmut")
    nproc, model, load_before = machine()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    rerun: list[str] = []
    if args.rerun:
        rerun = tests_again(workdir)
    else:
        prepare(args.package, workdir)
    start = time.perf_counter()
    mutmut(workdir, "run", "--max-children", "1", *rerun, log=workdir / "mutmut.log")
    wall = time.perf_counter() - start
    load_after = machine()[2]

    status = statuses(workdir)
    counts = Counter(status.values())
    survivors = sorted(n for n, s in status.items() if s == "survived")
    equivalent, stale = [], []
    for name, line in listed_equivalents().items():
        if not name.startswith(f"gentlerl.{args.package}."):
            continue
        if status.get(name) == "survived" and mutated_line(workdir, name) == line:
            equivalent.append(name)
        else:  # killed now, gone, or its line changed with the source
            stale.append(f"`{name}` ({status.get(name, 'no such mutant')})")
    total = len(status)
    killed = counts["killed"]
    score = killed / (total - len(equivalent)) if total > len(equivalent) else float("nan")
    detected = (killed + counts["timeout"]) / (total - len(equivalent)) if total else float("nan")

    rows = [("mutants total", total)] + [
        (s, counts[s]) for s in STATUSES if counts[s] or s in ("killed", "survived", "timeout")
    ]
    rows.append(("equivalent (marked, survived)", len(equivalent)))
    others = {s: c for s, c in counts.items() if s not in STATUSES}
    rows += sorted(others.items())
    table = ["| | mutants |", "| --- | ---: |"] + [f"| {k} | {v} |" for k, v in rows]
    table.append(
        f"| **score** killed / (total - equivalent) | **{killed}/{total - len(equivalent)} "
        f"= {100 * score:.1f} %** |"
    )
    table.append(f"| (killed + timeout) / (total - equivalent) | {100 * detected:.1f} % |")
    if total:
        table.append(
            f"| killed / total (nothing marked) | {killed}/{total} = {100 * killed / total:.1f} % |"
        )
    section = [
        f"## mutation: `gentlerl.{args.package}` against `{PACKAGES[args.package]}` "
        f"(`benchmarks/mutation.py`, {date})",
        "",
        f"{nproc} cores, {model}; load before: `{load_before}`; after: `{load_after}`. Commit "
        f"{commit}; mutmut {version}, one mutant at a time under `nice -n 19`, pytest "
        f"`{' '.join(PYTEST_ARGS)}`; {wall:.0f} s wall.{' ' + args.note if args.note else ''}"
        + (
            f" Re-run (`--rerun`): the {len(rerun)} mutants the last run in the work folder did "
            "not kill, against the tests copied in again; the others' verdicts are that run's."
            if rerun
            else ""
        ),
        "",
        f"Command: `{command}`",
        *(
            ["", "Deselected: " + ", ".join(f"`{t}`" for t in DESELECT[args.package])]
            if args.package in DESELECT
            else []
        ),
        "",
        *table,
    ]
    left = [n for n in survivors if n not in equivalent]
    if left:
        section += ["", "Survivors not marked equivalent: " + ", ".join(f"`{n}`" for n in left)]
    if equivalent:
        section += [
            "",
            f"Equivalent ({EQUIVALENT.name}): " + ", ".join(f"`{n}`" for n in equivalent),
        ]
    if stale:
        section += ["", "Listed as equivalent but not counted: " + "; ".join(stale)]
    text = "\n".join(section) + "\n"
    print(text)
    if args.survivors:
        for name in left:
            print(mutmut(workdir, "show", name))
    if args.record:
        with RESULTS.open("a") as f:
            f.write("\n" + text)


if __name__ == "__main__":
    main()
