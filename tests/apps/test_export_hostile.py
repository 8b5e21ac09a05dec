"""``gentlerl export`` refuses unknown tasks and a policy config that would steer it outside
``--out``."""

from __future__ import annotations

import pytest

from tests.helpers import policy_file


def test_export_refuses_unknown_tasks_and_an_empty_export(tmp_path, capsys):
    from gentlerl.apps.export import main as export

    with pytest.raises(SystemExit):
        export([str(tmp_path), "--tasks", "bogus"])
    assert "invalid choice: 'bogus'" in capsys.readouterr().err


def test_export_cannot_be_steered_outside_out_by_a_policy_config(tmp_path):
    from gentlerl.apps.export import main as export
    from gentlerl.training.checkpoint import CheckpointError, load_checkpoint, save_checkpoint

    path = policy_file(tmp_path, [16], [16])
    state = load_checkpoint(path)
    state["config"]["variant"] = "../../../escaped"
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    with pytest.raises(CheckpointError, match="variant='../../../escaped' is not one of"):
        export([str(tmp_path / "checkpoint.pt"), "--out", str(tmp_path / "out")])
    assert not list(tmp_path.parent.glob("escaped*")) and not (tmp_path / "out").exists()
