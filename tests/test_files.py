"""gentlerl.files and the run directory: nothing is written through a planted symbolic link."""

import os
import subprocess
import sys

import pytest

from gentlerl.files import LinkRefusedError, links_under, open_append, write_atomic
from gentlerl.training.run_lock import RunLock


def test_write_atomic_replaces_a_link_and_leaves_its_target_alone(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    link = tmp_path / "out.txt"
    link.symlink_to(victim)
    write_atomic(link, "new\n")
    assert victim.read_text() == "precious\n"
    assert not link.is_symlink() and link.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt", "victim.txt"]  # no temp left


def test_write_atomic_with_a_writer_and_bytes(tmp_path):
    write_atomic(tmp_path / "a.csv", lambda f: f.write("x,y\n1,2\n"), newline="")
    write_atomic(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "a.csv").read_text() == "x,y\n1,2\n"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"


def test_write_atomic_leaves_the_old_file_when_the_writer_fails(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("old")

    def fail(f):
        f.write("half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        write_atomic(path, fail)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_open_append_refuses_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    (tmp_path / "log").symlink_to(victim)
    with pytest.raises(LinkRefusedError, match="log is a symbolic link: gentlerl writes no file"):
        open_append(tmp_path / "log")
    assert victim.read_text() == "precious\n"
    with open_append(tmp_path / "real.log") as f:
        f.write("a\n")
    assert (tmp_path / "real.log").read_text() == "a\n"


def test_links_under_finds_file_and_folder_links_without_following_them(tmp_path):
    (tmp_path / "elsewhere").mkdir()
    run = tmp_path / "run"
    (run / "logs").mkdir(parents=True)
    (run / "logs" / "x.csv").symlink_to(tmp_path / "elsewhere" / "x")
    (run / "scalars").symlink_to(tmp_path / "elsewhere")
    assert sorted(p.name for p in links_under(run)) == ["scalars", "x.csv"]
    assert links_under(tmp_path / "elsewhere") == []


@pytest.mark.parametrize("name", [".lock", "config.yaml", "logs"])
def test_a_run_lock_refuses_a_run_dir_with_a_planted_link(tmp_path, name):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    run = tmp_path / "sl" / "d"
    run.mkdir(parents=True)
    (run / name).symlink_to(victim)
    with pytest.raises(LinkRefusedError, match=r"holds 1 symbolic link\(s\) .*: a run writes only"):
        RunLock(run).acquire()
    assert victim.read_text() == "precious\n"


def test_gentlerl_train_through_a_planted_lock_link_writes_nothing(tmp_path):
    """The finding: ``ln -s victim sl/d/.lock && gentlerl train run_dir=sl/d`` truncated it."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    run = tmp_path / "sl" / "d"
    run.mkdir(parents=True)
    (run / ".lock").symlink_to(victim)
    proc = subprocess.run(
        [sys.executable, "-m", "gentlerl", "train", f"run_dir={run}", "collector.total_frames=200"],
        capture_output=True, text=True, timeout=240, env={**os.environ, "GENTLERL_DEBUG": ""},
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert "symbolic link" in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert victim.read_text() == "precious\n"
    assert sorted(p.name for p in run.iterdir()) == [".lock"]


def _planted_folder(tmp_path):
    """A folder elsewhere and a link to it where a run's folder would be made."""
    victim = tmp_path / "elsewhere"
    victim.mkdir()
    return victim


@pytest.mark.parametrize("command", ["train", "seeds", "suite"])
def test_a_run_folder_that_is_itself_a_link_is_refused_before_anything_is_written(
    tmp_path, capsys, command
):
    """The finding: a seed folder planted as a link made ``gentlerl seeds``, ``train`` and ``suite
    run`` write checkpoint, config, logs and DONE into its target, outside ``--out``."""
    from gentlerl import cli
    from gentlerl.training import make_config, train
    from tests.helpers import TINY, toy_env

    victim = _planted_folder(tmp_path)
    if command == "train":
        (tmp_path / "run").symlink_to(victim)
        cfg = make_config("cpu", **TINY, run_dir=str(tmp_path / "run"))
        with pytest.raises(LinkRefusedError, match=r"run_dir='.*run' is a symbolic link: a run"):
            train(cfg, toy_env)
    elif command == "seeds":
        (tmp_path / "g").mkdir()
        (tmp_path / "g" / "seed1").symlink_to(victim)
        assert cli.main(["seeds", "0", "1", "--out", str(tmp_path / "g")]) == 1
        err = capsys.readouterr().err
        assert "seed1' is a symbolic link: a run writes only into folders it makes" in err
        assert err.count("\n") == 1 and not (tmp_path / "g" / "seed0").exists()
    else:
        from gentlerl.apps.suite import SuiteRefused, plan_suite
        from gentlerl.apps.suite_files import load_suite
        from tests.apps.test_suite import EXAMPLE

        (tmp_path / "out" / "toy" / "r").mkdir(parents=True)
        (tmp_path / "out" / "toy" / "r" / "seed0").symlink_to(victim)
        with pytest.raises(SuiteRefused, match="seed0' is a symbolic link: a run writes only"):
            plan_suite(load_suite(EXAMPLE), tmp_path / "out")
    assert list(victim.iterdir()) == []


def _hostile_file(tmp_path, kind, name="hostile"):
    """A path that is a link to a real file, a FIFO, a link to /dev/zero or a 2 GiB sparse file."""
    path = tmp_path / name
    if kind == "link":
        (tmp_path / "real").write_text("a: 1\n")
        path.symlink_to(tmp_path / "real")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    else:
        with open(path, "wb") as f:
            f.truncate(2 << 30)  # sparse: no disk, but 2 GiB to a reader that reads it
    return path


KINDS = {
    "link": "is a symbolic link: gentlerl reads no file through a link",
    "fifo": "is a FIFO, not a regular file",
    "dev-zero": "is a symbolic link",
    "sparse": "is 2,147,483,648 bytes, over the",
}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_open_checked_refuses_by_fstat_before_reading(tmp_path, kind):
    from gentlerl.files import FileRefusedError, open_checked, read_checked

    path = _hostile_file(tmp_path, kind)
    with pytest.raises(FileRefusedError, match=f"{path} {KINDS[kind]}"):
        read_checked(path)
    if kind == "sparse":  # no cap: the reader's choice
        open_checked(path, cap=None).close()
    (tmp_path / "zero").symlink_to("/dev/zero")
    with pytest.raises(FileRefusedError, match="is a symbolic link"):
        open_checked(tmp_path / "zero")


def _read_with(reader, path):
    from gentlerl.analysis.claims import load_final_evals
    from gentlerl.analysis.results import read_results
    from gentlerl.apps.suite_files import load_suite
    from gentlerl.apps.sweep_files import load_sweep
    from gentlerl.training.checkpoint import load_checkpoint
    from gentlerl.training.resume import _history

    if reader == "final_evals":
        return load_final_evals(path.parent)
    if reader == "run config (plot)":
        from gentlerl.analysis.runs import load_run

        return load_run(path.parent)
    return {
        "sweep": load_sweep, "suite": load_suite, "results (table)": read_results,
        "checkpoint": load_checkpoint, "config history": _history,
    }[reader](path)  # fmt: skip


@pytest.mark.parametrize(
    "reader",
    [
        "sweep",
        "suite",
        "results (table)",
        "checkpoint",
        "config history",
        "final_evals",
        "run config (plot)",
    ],
)
@pytest.mark.parametrize("kind", ["fifo", "sparse", "dev-zero"])
def test_every_reader_refuses_a_fifo_a_device_and_a_huge_file_unread(tmp_path, reader, kind):
    """The findings: a 2 GiB sparse file cost 4.2 GB in sweep, suite, plot and the method3 table;
    /dev/zero links 7-8 GB; a FIFO hung."""
    import resource

    folder = tmp_path / "hostile"
    folder.mkdir()
    name = {"final_evals": "final_eval.jsonl", "run config (plot)": "config.yaml"}.get(reader, "f")
    path = _hostile_file(folder, kind, name)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises((OSError, ValueError)) as err:
        _read_with(reader, path)
    assert "\n" not in str(err.value) and "hostile" in str(err.value)
    # a checkpoint has no size cap (a paper-scale one holds its replay): torch reads its header
    expected = [*KINDS.values(), *(["cannot read checkpoint"] if reader == "checkpoint" else [])]
    assert any(fragment in str(err.value) for fragment in expected), str(err.value)
    grown_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
    assert grown_kib < 200_000  # nothing of the 2 GiB was read


def test_yaml_reads_yaml_1_2_core_numbers_and_dump_yaml_round_trips_words_that_look_like_them():
    from gentlerl.files import dump_yaml, load_yaml

    assert load_yaml("[010, 1e-3, .5, 1., -.inf, 1:04, 1_000, 0x10, yes, 2024-01-01]") == [
        10, 0.001, 0.5, 1.0, float("-inf"), "1:04", "1_000", "0x10", "yes", "2024-01-01",
    ]  # fmt: skip
    words = {"a": "1e-3", "b": "010", "c": "on", "d": "null", "e": "", "f": ".nan", "g": 1e-05}
    assert load_yaml(dump_yaml(words)) == words


def test_a_file_that_is_not_utf8_is_one_line_naming_it(tmp_path):
    from gentlerl.apps.sweep_files import load_sweep
    from gentlerl.files import FileRefusedError

    (tmp_path / "s.yaml").write_bytes(b"parameters:\n  seed: \xff\n")
    with pytest.raises(FileRefusedError, match=r"s.yaml is not UTF-8 text \(byte 20\)"):
        load_sweep(tmp_path / "s.yaml")
