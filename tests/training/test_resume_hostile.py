"""The config history of a resumed run: empty is no change, a mapping is refused."""

from __future__ import annotations

import pytest


def test_an_empty_config_history_does_not_crash_a_resume(tmp_path):
    from gentlerl.config.layout import CONFIG_HISTORY
    from gentlerl.training.resume import record_config_changes

    (tmp_path / CONFIG_HISTORY).write_text("")
    state = {"counters": {"frames": 10}, "config": {"seed": 0, "logging": {"eval_episodes": 1}}}
    now = {"seed": 0, "logging": {"eval_episodes": 2}}
    assert record_config_changes(tmp_path, state, now) == ["logging.eval_episodes"]
    (tmp_path / CONFIG_HISTORY).write_text("a: mapping\n")
    with pytest.raises(ValueError, match="must be a YAML list"):
        record_config_changes(tmp_path, state, now)
