"""``gentlerl calibration`` refuses a checkpoint of huge sizes before building, bounds its episodes
and checks its JSON output first."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize(
    ("group", "name", "value"),
    [
        ("network", "critic_hidden", [100000, 100000]),
        ("gentleness", "ensemble_size", 1000000),
        ("gentleness", "model_hidden", 1000000),
    ],
)
def test_calibration_refuses_a_checkpoint_of_huge_sizes_before_building(
    tmp_path, group, name, value
):
    from gentlerl.apps.calibration import critic_calibration
    from gentlerl.models import make_actor
    from gentlerl.training.checkpoint import save_checkpoint
    from gentlerl.training.config import preset_config

    config = preset_config().to_dict()
    config[group][name] = value
    state = {"config": config, "obs_dim": 63, "action_dim": 20, "learner": {}, "intrinsic": {}}
    save_checkpoint(tmp_path / "checkpoint.pt", {**state, "actor": make_actor(63, 20).state_dict()})
    with pytest.raises(
        ValueError, match=rf"its config is invalid: {group}.{name}=.* must be in \["
    ):
        critic_calibration(tmp_path, episodes=1)


def test_calibration_bounds_its_episodes_and_checks_its_json_before_the_rollouts(tmp_path):
    from gentlerl.apps.calibration import critic_calibration, main

    with pytest.raises(ValueError, match=r"episodes must be an integer in \[1, 256\]"):
        critic_calibration(tmp_path / "none", episodes=100000)
    (tmp_path / "checkpoint.pt").write_bytes(b"")  # never read: the output is checked first
    with pytest.raises(SystemExit) as err:
        main([str(tmp_path), "--json", str(tmp_path / "checkpoint.pt" / "x.json")])
    assert "error: --json " in str(err.value.code) and "is not a directory" in str(err.value.code)
