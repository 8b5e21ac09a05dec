"""The ``gentlerl`` command: one line per refusal on stderr and exit 1, the traceback only when asked."""

from __future__ import annotations

import pytest


def test_a_refusal_is_one_line_on_stderr_and_exit_1(tmp_path, capsys, monkeypatch):
    from gentlerl.cli import main

    monkeypatch.setenv("GENTLERL_DEBUG", "0")  # restored afterwards, also after --debug sets it
    assert main(["evaluate", str(tmp_path / "none.pt")]) == 1
    err = capsys.readouterr().err
    assert err == f"gentlerl evaluate: error: no checkpoint at {tmp_path / 'none.pt'}\n"
    with pytest.raises(FileNotFoundError):
        main(["evaluate", str(tmp_path / "none.pt"), "--debug"])
    monkeypatch.setenv("GENTLERL_DEBUG", "1")
    with pytest.raises(FileNotFoundError):
        main(["plot", str(tmp_path / "none")])
