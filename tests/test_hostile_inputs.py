"""Hostile inputs and faults (issue 23): each probe refused in one line, nothing written where it
must not be, and safety checks that fail closed."""

from __future__ import annotations

from pathlib import Path

import pytest

from gentlerl.sweeps import main as sweep


def _sweep_file(tmp_path: Path, body: str) -> str:
    path = tmp_path / "evil.yaml"
    path.write_text(body)
    return str(path)


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


# --- sweep files cannot run code or write outside --out -------------------------------------


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("+hydra.callbacks.a._target_", "numpy.savetxt"),
        ("hydra.run.dir", "x"),
        ("_target_", "builtins.open"),
        ("++seed", 1),
        ("+foo", 1),
        ("not_a_field", 1),
        ("network", 1),
        ("env.kwargs", 1),
        ("run_dir", "x"),
    ],
)
def test_sweep_keys_must_be_config_fields(tmp_path, key, value, capsys):
    path = _sweep_file(tmp_path, f"parameters:\n  '{key}': {{values: [{value}]}}\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as err:
        sweep([path, "--out", str(out)])
    message = str(err.value.code)
    assert repr(key) in message and "\n" not in message
    assert not out.exists()


def test_a_sweep_callback_payload_writes_nothing(tmp_path):
    target = tmp_path / "pwned.txt"
    body = (
        "parameters:\n  seed: {values: [0]}\n"
        f"  +hydra.callbacks.a._target_: {{value: numpy.savetxt}}\n"
        f"  +hydra.callbacks.a._args_: {{value: ['{target}', [1, 2]]}}\n"
    )
    with pytest.raises(SystemExit, match="hydra"):
        sweep([_sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert not target.exists()


@pytest.mark.parametrize(
    "value",
    ["r/../../../../x", "..", "a b", "${oc.env:HOME}", "r,x", "x=y", "'q'", "/abs"],
)
def test_sweep_values_cannot_leave_out(tmp_path, value):
    path = _sweep_file(tmp_path, f"parameters:\n  variant: {{values: [{value!r}]}}\n")
    before = _files(tmp_path)
    with pytest.raises(SystemExit, match="string value may hold only"):
        sweep([path, "--out", str(tmp_path / "out"), "--dry-run"])
    assert _files(tmp_path) == before


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("", "expected a mapping"),
        ("- a\n- b\n", "expected a mapping"),
        ("parameters: [1, 2]\n", "must be a mapping"),
        ("parameters: {seed: {values: []}}\n", "needs `values:`"),
        ("parameters: {seed: 3}\n", "needs `values:`"),
        ("parameters: {seed: {values: [[[1]]]}}\n", "nested lists"),
        ("parameters: {seed: {values: [{a: 1}]}}\n", "expected a number"),
        ("parameters: {seed: [\n", "not valid YAML"),
    ],
)
def test_malformed_sweep_files_are_one_line_refusals(tmp_path, body, match):
    with pytest.raises(SystemExit, match=match) as err:
        sweep([_sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert "\n" not in str(err.value.code)


def test_missing_sweep_file_and_bad_set_are_refused(tmp_path):
    with pytest.raises(SystemExit, match="No such file"):
        sweep([str(tmp_path / "none.yaml"), "--out", str(tmp_path)])
    good = _sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    for item in ("hydra.job.chdir=true", "+hydra.callbacks.a._target_=os.system", "seed"):
        with pytest.raises(SystemExit, match="--set"):
            sweep([good, "--out", str(tmp_path / "o"), "--set", item, "--dry-run"])
    assert sweep([good, "--out", str(tmp_path / "o"), "--dry-run", "--set",
                  "+env.kwargs.calibration=easy"]) == 0  # fmt: skip
