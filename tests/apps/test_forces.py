"""``gentlerl forces``: an env's contact statistics and the force-tolerance rule's scale."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from gentlerl.apps import forces
from gentlerl.apps.forces import force_profile, tolerance_force_scale


def _episode(impacts: list[list[float]], force: list[list[float]] | None = None) -> TensorDict:
    """A ``[T]`` rollout whose ``next`` holds ``impact`` ``[T, sites]`` (and ``force``)."""
    impact = torch.tensor(impacts)
    nxt = {"impact": impact}
    if force is not None:
        nxt["force"] = torch.tensor(force).unsqueeze(-1)
    return TensorDict({"next": TensorDict(nxt, [len(impacts)])}, [len(impacts)])


def test_profile_counts_contact_steps_and_quantiles_by_hand():
    # Episode 1: 4 steps, 2 sites; contact where an impact is > 0 or the force after it is.
    touching = _episode(
        [[0.0, 0.0], [3.0, 1.0], [0.0, 0.0], [0.0, 5.0]],
        force=[[0.0, 0.0], [3.0, 1.0], [2.0, 0.0], [0.0, 5.0]],
    )
    # Episode 2: never touches.
    idle = _episode([[0.0, 0.0]] * 4, force=[[0.0, 0.0]] * 4)
    p = force_profile([touching, idle])
    assert p["steps"] == 8 and p["episodes"] == 2
    assert p["contact_share"] == pytest.approx(3 / 8)  # steps 2, 3 (force, no impact), 4
    assert p["touching_share"] == 0.5
    # Per-step largest impact on the 3 contact steps: 3, 0, 5.
    assert p["step_impact_median"] == pytest.approx(3.0)
    assert p["episode_max_median"] == pytest.approx(2.5)  # episodes' max: 5 and 0
    assert p["touching_max_median"] == pytest.approx(5.0)  # the rule's statistic: 5 only
    # eq. 4 at lambda = [2, 2]: -(1 - sigmoid(2 (2 - m))) m summed over sites and steps.
    pen = -sum((1 - 1 / (1 + math.exp(2 * (m - 2)))) * m for m in (3.0, 1.0, 5.0))
    assert p["episode_penalty_median"] == pytest.approx(pen / 2, rel=1e-6)  # median of pen, 0


def test_profile_penalty_reads_the_scaled_force():
    ep = _episode([[100.0]], force=[[100.0]])
    # Read at 0.02, a 100 N impact is 2 "hand newtons": the penalty of eq. 4 at m = 2 is -1.
    assert force_profile([ep], force_scale=0.02)["episode_penalty_median"] == pytest.approx(-1.0)


def test_rule_maps_the_envs_statistic_onto_the_hands():
    assert tolerance_force_scale(240.0, 4.0) == pytest.approx(1 / 60)
    assert tolerance_force_scale(4.0, 4.0) == 1.0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan"), "3"])
def test_rule_refuses_an_env_that_never_touched(bad):
    with pytest.raises(ValueError, match="env_impact"):
        tolerance_force_scale(bad, 4.0)


def test_profile_refuses_no_episodes():
    with pytest.raises(ValueError, match="at least one episode"):
        force_profile([])


def test_command_on_finger_spin_prints_the_rule_and_measures_in_newtons(capsys):
    result = forces.main(
        ["dm_control:finger-spin", "--episodes", "1", "--reference-impact", "4.06"]
    )
    out = capsys.readouterr().out
    assert "env.force_scale=" in out and "finger-spin" in out
    assert result["steps"] == 1000  # one dm_control episode
    # Random actions on finger-spin hit in the hundreds of newtons (the reason for the rule).
    assert result["touching_max_median"] > 50.0
    assert result["force_scale"] == pytest.approx(4.06 / result["touching_max_median"])


def test_command_on_walker_reads_the_feets_contact_forces(capsys):
    result = forces.main(["dm_control:walker-walk", "--episodes", "1", "--reference-impact", "4"])
    out = capsys.readouterr().out
    assert "walker-walk" in out and "env.force_scale=" in out
    assert result["steps"] == 1000 and result["contact_share"] > 0.1  # feet on the floor
    # random actions stamp the feet: impacts of tens to hundreds of N (the walker weighs 280 N)
    assert 10.0 < result["step_impact_median"] < result["touching_max_median"]


def test_command_measures_named_contact_groups_and_refuses_them_on_the_hand(capsys):
    # Gymnasium's Hopper: random actions fall within a few dozen steps (short episodes)
    argv = ["gym:Hopper-v5", "--episodes", "2", "--reference-impact", "4", "--json"]
    foot = forces.main([*argv, "--group", "foot=foot"])
    capsys.readouterr()
    body = forces.main([*argv, "--group", "body=subtree:torso"])
    # the same seeded episodes: the whole hopper touches at least as often as its foot
    assert body["steps"] == foot["steps"] < 200
    assert body["contact_share"] >= foot["contact_share"] > 0.0
    with pytest.raises(
        ValueError, match=r"'toes' is no body of the model; bodies: \['world', 'torso'"
    ):
        forces.main([*argv, "--group", "t=toes"])
    with pytest.raises(ValueError, match="--group names the contact force sites of an external"):
        forces.main(["touch", "--episodes", "1", "--group", "f=ff_distal"])
    with pytest.raises(SystemExit):
        forces.main([*argv, "--group", "feet"])


def test_command_names_an_unknown_env():
    with pytest.raises(ValueError, match="no task finger-nope"):
        forces.main(["dm_control:finger-nope", "--episodes", "1", "--reference-impact", "1"])


def test_a_policy_measured_under_another_env_name_is_refused():
    """The finding: ``forces ENV --policy hand_policy.pt`` printed the hand's numbers as ENV's."""
    policy = Path(__file__).resolve().parents[2] / "docs/policies/touch/r/seed0.pt"
    with pytest.raises(ValueError, match=r"acts on 'touch' .* ENV is 'dm_control:finger-spin'"):
        forces.measure("dm_control:finger-spin", 1, policy=str(policy))
