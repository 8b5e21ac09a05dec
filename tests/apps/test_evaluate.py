"""``gentlerl evaluate``: a saved policy's success, broken rate and impacts."""

import json
import math

import pytest
import torch

from gentlerl.apps.evaluate import evaluate_policy, main
from gentlerl.models import make_actor
from gentlerl.training import make_config, save_checkpoint
from gentlerl.training.evaluation import summarize

INDEX_KNUCKLE = 3  # actuator robot0:A_FFJ2


def _scripted_policy(path, push: float, task: str = "fragile"):
    """A checkpoint whose actor always outputs ``push`` on the index knuckle, 0 elsewhere."""
    cfg = make_config(task=task, network={"actor_hidden": (8,)})
    actor = make_actor(63, 20, cfg.network.actor_hidden)
    last = actor.module[-2]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.zero_()
        last.bias[INDEX_KNUCKLE] = math.atanh(push)
    state = {"config": cfg.to_dict(), "obs_dim": 63, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(path, state)
    return path


def test_summarize_rates_and_impact_percentiles():
    episodes = [
        {"success": s, "broken": b, "max_impact": m}
        for s, b, m in [(1, 0, 1.0), (1, 0, 2.0), (0, 1, 4.0), (0, 0, 0.0)]
    ]
    out = summarize(episodes)
    assert out["episodes"] == 4 and out["success_rate"] == 0.5 and out["broken_rate"] == 0.25
    assert out["median_max_impact"] == 1.5
    assert out["p90_max_impact"] == pytest.approx(3.4)  # numpy's linear interpolation
    with pytest.raises(ValueError, match="at least one episode"):
        summarize([])


def test_full_press_breaks_and_gentle_press_succeeds(tmp_path):
    fast = evaluate_policy(_scripted_policy(tmp_path / "fast.pt", 0.999), 3, seed=1)
    assert fast["task"] == "fragile" and fast["broken_rate"] == 1.0 and fast["success_rate"] == 0.0
    assert fast["median_max_impact"] > 3.0  # the break threshold
    slow = evaluate_policy(_scripted_policy(tmp_path / "slow.pt", 0.25), 3, seed=1)
    assert slow["success_rate"] == 1.0 and slow["broken_rate"] == 0.0
    assert slow["p90_max_impact"] < 3.0
    # The earlier, easier hand: the same full-speed press stays below the break threshold.
    easy = evaluate_policy(tmp_path / "fast.pt", 3, regime="easy", seed=1)
    assert easy["success_rate"] == 1.0 and easy["p90_max_impact"] < 3.0


def test_cli_prints_json_and_checks_its_input(tmp_path, capsys):
    path = _scripted_policy(tmp_path / "p.pt", 0.999, task="touch")
    main([str(path), "--episodes", "2", "--task", "touch", "--seed", "0", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert out["task"] == "touch" and out["episodes"] == 2 and out["success_rate"] == 1.0
    assert out["policy"] == str(path)
    with pytest.raises(ValueError, match=r"episodes must be an integer in \[1, 10,000\], got 0"):
        evaluate_policy(path, 0)
    with pytest.raises(ValueError, match="unknown task 'grasp'"):
        evaluate_policy(path, 1, task="grasp")
    with pytest.raises(FileNotFoundError, match="no checkpoint at"):
        evaluate_policy(tmp_path / "missing.pt", 1)


@pytest.mark.parametrize("argv", [["--calibration", "easy"], ["--calibration=easy"]])
def test_the_regimes_earlier_option_is_refused_in_one_line_naming_the_new_one(argv, tmp_path):
    with pytest.raises(SystemExit) as refused:
        main([str(tmp_path / "p.pt"), *argv])
    assert str(refused.value) == (
        "gentlerl evaluate: --calibration is now --regime (the hand's physics regime)"
    )
