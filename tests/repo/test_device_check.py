"""benchmarks/device_check.sh against a shared temporary folder: its packages unpacked where only
its user can write, removed on exit; a table or log planted in OUT_DIR as a link refused, never
written through; the table renamed into place. Run with a stand-in python and the ``env``
section only (no GPU, no packages, well under a second)."""

import os
import stat
import subprocess
import tarfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "device_check.sh"

#: A python that has nothing (so the script unpacks its site) and records the first folder of its
#: PYTHONPATH, with its mode and owner, when it holds the site's marker.
STUB = """#!/bin/sh
site="${PYTHONPATH%%:*}"
[ -f "$site/site_marker.py" ] && echo "$site $(stat -c '%a %u' "$site")" >> "$STUB_LOG"
exit 1
"""


def _run(tmp_path: Path, out: Path, *sections: str) -> subprocess.CompletedProcess:
    stub = tmp_path / "python"
    stub.write_text(STUB)
    stub.chmod(0o755)
    marker = tmp_path / "site_marker.py"
    marker.write_text("")
    with tarfile.open(tmp_path / "site.tgz", "w:gz") as tar:
        tar.add(marker, arcname="site_marker.py")
    scratch = tmp_path / "tmp"
    scratch.mkdir(exist_ok=True)
    env = {
        **os.environ,
        "PYTHON": str(stub),
        "STUB_LOG": str(tmp_path / "stub.log"),
        "SITE_TGZ": str(tmp_path / "site.tgz"),
        "TMPDIR": str(scratch),
    }
    return subprocess.run(
        ["bash", str(SCRIPT), str(out), *(sections or ("env",))],
        env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_the_site_is_unpacked_in_a_private_folder_removed_on_exit(tmp_path):
    done = _run(tmp_path, tmp_path / "out")
    assert done.returncode == 0, done.stderr
    seen = {tuple(line.split()) for line in (tmp_path / "stub.log").read_text().splitlines()}
    assert len(seen) == 1, seen  # one folder, the same for every python the script ran
    site, mode, owner = seen.pop()
    assert (mode, owner) == ("700", str(os.getuid()))  # only its user may write there
    assert Path(site).is_relative_to(tmp_path / "tmp")  # TMPDIR, not a fixed /tmp folder
    assert list((tmp_path / "tmp").iterdir()) == []  # removed on exit
    table = tmp_path / "out" / "device_table.md"
    assert table.read_text().startswith("## device_check, ") and stat.S_ISREG(table.lstat().st_mode)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["device_table.md"]


@pytest.mark.parametrize("name", ["device_table.md", "device_log.txt"])
def test_a_table_or_log_planted_as_a_link_is_refused_and_its_target_untouched(tmp_path, name):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.write_text("precious\n")
    (out / name).symlink_to(victim)
    done = _run(tmp_path, out)
    assert done.returncode != 0
    assert done.stderr.strip().count("\n") == 0 and name in done.stderr, done.stderr
    assert victim.read_text() == "precious\n"
    assert sorted(p.name for p in out.iterdir()) == [name]  # nothing else written


def test_a_table_that_is_a_folder_or_an_unknown_section_is_refused_in_one_line(tmp_path):
    out = tmp_path / "out"
    (out / "device_table.md").mkdir(parents=True)
    done = _run(tmp_path, out)
    assert done.returncode != 0 and "not a regular file" in done.stderr
    assert done.stderr.strip().count("\n") == 0
    done = _run(tmp_path, tmp_path / "out2", "env", "lerner")
    assert done.returncode == 2 and "unknown section 'lerner'" in done.stderr
    assert not (tmp_path / "out2").exists()


def test_a_previous_table_is_replaced_whole(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "device_table.md").write_text("old table\n")
    done = _run(tmp_path, out)
    assert done.returncode == 0, done.stderr
    assert (out / "device_table.md").read_text().startswith("## device_check, ")
    assert not list(out.glob(".device_table.*"))  # the temporary file renamed into place


def test_a_relative_out_dir_is_the_callers_and_an_option_is_refused(tmp_path):
    """The findings: a relative OUT_DIR landed in the checkout (the script moves there); ``-x``
    was taken as a folder name."""
    stub = tmp_path / "python"
    stub.write_text(STUB)
    stub.chmod(0o755)
    env = {**os.environ, "PYTHON": str(stub), "STUB_LOG": str(tmp_path / "stub.log")}
    caller = tmp_path / "caller"
    caller.mkdir()
    done = subprocess.run(
        ["bash", str(SCRIPT), "rel_out", "env"], cwd=caller, env=env, capture_output=True,
        text=True, timeout=60,
    )  # fmt: skip
    assert (caller / "rel_out" / "device_table.md").is_file(), done.stderr
    assert not (ROOT / "rel_out").exists()
    done = subprocess.run(
        ["bash", str(SCRIPT), "-x"], cwd=caller, env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and "'-x' is not an OUT_DIR (it takes no options" in done.stderr
    assert done.stderr.count("\n") == 1 and not (caller / "-x").exists()
