"""Critic calibration diagnostic: discounted returns, expected values and their comparison on
hand-computed numbers, end to end on the toy env with a critic of known constant output, the
``gentlerl calibration`` command and the evaluation-time scalars of a run."""

import json
import math

import pytest
import torch
from torchrl.envs import TransformedEnv

from gentlerl import cli, keys
from gentlerl.apps.calibration import _sources_line
from gentlerl.apps.calibration import main as calibration_main
from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.training.checkpoint import save_checkpoint
from gentlerl.training.critic_calibration import (
    SOURCE_SCALARS,
    calibration_scalars,
    calibration_stats,
    discounted_returns,
    expected_value,
    measure_calibration,
    penalty_surprise_sources,
)
from gentlerl.training.evaluation import rollout_episodes
from gentlerl.transforms import ImpactPenalty
from tests.helpers import make_reward_transforms, pressing_rollout, read_scalar, tiny_config
from tests.toy_env import ToyHandEnv

F, T = False, True


# --- the pure functions -------------------------------------------------------------------
def test_discounted_returns_bootstrap_at_truncation_and_stop_at_a_cut():
    rewards, done = torch.ones(3), torch.tensor([F, F, T])
    # G2 = 1 + 0.5 * 4 = 3, G1 = 1 + 0.5 * 3 = 2.5, G0 = 1 + 0.5 * 2.5 = 2.25
    truncated = discounted_returns(rewards, done, torch.full((3,), 4.0), 0.5)
    assert truncated.tolist() == [2.25, 2.5, 3.0]
    # Terminated (an episodic head): no bootstrap, G2 = 1, G1 = 1.5, G0 = 1.75.
    cut = discounted_returns(rewards, done, torch.full((3,), 4.0), 0.5, cut=done)
    assert cut.tolist() == [1.75, 1.5, 1.0]


def test_discounted_returns_of_two_episodes_episodic_and_non_episodic_heads():
    # Two episodes laid end to end: [1, 2] terminated (next-state value 10), then [3, 4] cut by
    # the rollout's end (next-state value 8); gamma 0.5. Head 0 is episodic, head 1 is not.
    rewards = torch.tensor([[1.0, 2.0, 3.0, 4.0]] * 2)
    done = torch.tensor([F, T, F, F])
    bootstrap = torch.tensor([[0.0, 10.0, 0.0, 8.0]] * 2)
    terminated = torch.tensor([F, T, F, F])
    cut = terminated & torch.tensor([[T], [F]])
    returns = discounted_returns(rewards, done, bootstrap, 0.5, cut)
    # episodic: G1 = 2, G0 = 1 + 1 = 2; G3 = 4 + 4 = 8, G2 = 3 + 4 = 7 (no sum across episodes)
    assert returns[0].tolist() == [2.0, 2.0, 7.0, 8.0]
    # non-episodic: G1 = 2 + 0.5 * 10 = 7, G0 = 1 + 3.5 = 4.5
    assert returns[1].tolist() == [4.5, 7.0, 7.0, 8.0]
    with pytest.raises(ValueError, match="gamma"):
        discounted_returns(rewards, done, bootstrap, 1.5)


def test_expected_value_of_categorical_distributions():
    # softmax([0, 0]) on [-1, 3]: 1; softmax([log 3, 0]) = [0.75, 0.25] on [0, 4]: 1.
    logits = torch.tensor([[0.0, 0.0], [math.log(3.0), 0.0]])
    atoms = torch.tensor([[-1.0, 3.0], [0.0, 4.0]])
    assert torch.allclose(expected_value(logits, atoms), torch.tensor([1.0, 1.0]))
    assert expected_value(torch.zeros(4, 3, 5), torch.linspace(-2, 2, 5).expand(4, 3, 5)).shape == (
        4,
        3,
    )
    with pytest.raises(ValueError, match="differ"):
        expected_value(torch.zeros(2, 3), torch.zeros(2, 4))


def test_calibration_stats_on_hand_computed_numbers():
    s = calibration_stats(torch.tensor([0.0, 0.0]), torch.tensor([-4.0, -16.0]), -10.0, 0.0)
    # mean realised -10, bias 0 - (-10) = 10, |bias| / 10 = 1, -16 is below the support
    assert s == {
        "predicted": 0.0,
        "realised": -10.0,
        "bias": 10.0,
        "mae": 10.0,
        "rel_error": 1.0,
        "outside_support": 0.5,
    }
    # A realised mean near 0 is divided by eps (0.1), not by itself.
    assert calibration_stats(torch.tensor([0.05]), torch.tensor([0.0]), -1, 1)[
        "rel_error"
    ] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="non-empty"):
        calibration_stats(torch.zeros(0), torch.zeros(0), -1, 1)


# --- end to end: a critic of known constant output on the toy env -------------------------
GAMMA = 0.9


def _agent(press: bool, non_episodic=()):
    """Actor: every action 0 (never touches) or joint 0 at +1 (the toy's press succeeds at its
    8th step). Critic: head ``reward`` predicts 2.0 (all mass on atom 60 of [-10, 10]), head
    ``penalty`` 5.0 below 0 (uniform on [-10, 0]), whatever the state and action."""
    actor = make_actor(63, 20, (8,))
    critic = make_critic(63, 20, 2, (8,), num_atoms=101, v_min=-10.0, v_max=[10.0, 0.0])
    with torch.no_grad():
        for p in [*actor.module[-2].parameters(), *critic.module.head.parameters()]:
            p.zero_()
        actor.module[-2].bias[0] = 20.0 if press else 0.0  # tanh(20) = 1
        critic.module.head.bias.view(2, -1)[0, 60] = 50.0  # atom 60 = -10 + 60 * 0.2 = 2
    loss = MultiHeadD4PGLoss(
        actor, critic, reward_keys=["reward", "penalty"], non_episodic_keys=non_episodic
    )
    loss.make_value_estimator(gamma=GAMMA)
    return loss


def _episodes(loss, episodes=2, time_limit=10):
    env = TransformedEnv(ToyHandEnv(time_limit=time_limit), ImpactPenalty())
    return rollout_episodes(env, loss.actor_network, episodes, 1000)


def test_truncated_episodes_are_bootstrapped_with_the_critics_own_value():
    loss = _agent(press=False)
    episodes = _episodes(loss)
    before = [e.clone() for e in episodes]
    report = measure_calibration(loss, ImpactPenalty(), episodes, GAMMA)
    assert all((a == b).all() for a, b in zip(episodes, before, strict=True))  # not modified
    # No touch, no reward: G_t = gamma^(10 - t) * Q(s_10) with Q = 2 (reward), -5 (penalty).
    discount = torch.tensor([GAMMA ** (10 - t) for t in range(10)], dtype=torch.float64)
    for head, q in (("reward", 2.0), ("penalty", -5.0)):
        for where, factor in (("all", discount.mean()), ("start", discount[0])):
            s = report[head][where]
            assert s["predicted"] == pytest.approx(q, abs=1e-5)
            assert s["realised"] == pytest.approx(q * float(factor), abs=1e-5)
            assert s["bias"] == pytest.approx(q * (1 - float(factor)), abs=1e-5)
            assert s["outside_support"] == 0.0
            assert s["bootstrap"] == pytest.approx(s["realised"], abs=1e-5)  # no reward at all
    # mean of gamma^1..gamma^10 = 0.9 (1 - 0.9^10) / (10 * 0.1) = 0.58619
    assert report["reward"]["all"]["realised"] == pytest.approx(2 * 0.586189, abs=1e-5)
    scalars = calibration_scalars(report)
    assert sorted(scalars) == [
        f"calibration/{h}/{s}"
        for h in ("penalty", "reward")
        for s in ("bias", "predicted", "realised")
    ]


def test_termination_cuts_episodic_heads_and_not_the_others():
    episodic, through = _agent(press=True), _agent(press=True, non_episodic=["penalty"])
    episodes = _episodes(episodic, time_limit=50)
    assert [e.shape[0] for e in episodes] == [8, 8]  # the press succeeds at step 8
    cut = measure_calibration(episodic, ImpactPenalty(), episodes, GAMMA)
    kept = measure_calibration(through, ImpactPenalty(), episodes, GAMMA)
    # Task reward +1 at the terminal step, no bootstrap: G_t = 0.9^(7 - t), G_0 = 0.4783.
    assert cut["reward"]["start"]["realised"] == pytest.approx(GAMMA**7, abs=1e-6)
    assert kept["reward"] == cut["reward"] and cut["reward"]["all"]["bootstrap"] == 0.0
    # The non-episodic penalty head adds gamma^(8 - t) * Q(s_8) = gamma^(8 - t) * (-5).
    extra = kept["penalty"]["start"]["realised"] - cut["penalty"]["start"]["realised"]
    assert extra == pytest.approx(-5.0 * GAMMA**8, abs=1e-5)
    assert kept["penalty"]["start"]["bootstrap"] == pytest.approx(-5.0 * GAMMA**8, abs=1e-5)
    mean_extra = -5.0 * sum(GAMMA ** (8 - t) for t in range(8)) / 8
    assert kept["penalty"]["all"]["realised"] - cut["penalty"]["all"]["realised"] == pytest.approx(
        mean_extra, abs=1e-5
    )
    with pytest.raises(ValueError, match="at least one episode"):
        measure_calibration(episodic, ImpactPenalty(), [], GAMMA)


# --- the command and the run's logs -------------------------------------------------------
@pytest.fixture(scope="module")
def hand_run(tmp_path_factory):
    """A 300-frame r+rf+rsp run on the hand (30-step episodes, curiosity on from the start)."""
    from gentlerl.training import train

    run_dir = tmp_path_factory.mktemp("run")
    cfg = tiny_config(
        run_dir, seed=3, variant="r+rf+rsp", total_frames=300, reward_delay=0,
        kwargs={"time_limit": 30, "action_scale": 0.3}, eval_every_frames=300,
        eval_episodes=2, log_every_updates=25,
    )  # fmt: skip
    train(cfg)
    return run_dir


def test_a_run_logs_each_heads_calibration_at_evaluation(hand_run):
    for head in ("reward", "penalty", "penalty_surprise"):
        for stat in ("predicted", "realised", "bias"):
            rows = read_scalar(hand_run, f"calibration/{head}/{stat}")
            assert [step for step, _ in rows] == [300] and math.isfinite(rows[0][1])
        (_, p), (_, g), (_, b) = (
            read_scalar(hand_run, f"calibration/{head}/{s}")[0]
            for s in ("predicted", "realised", "bias")
        )
        assert b == pytest.approx(p - g, abs=1e-5)


def test_calibration_command_prints_every_head_and_mode(hand_run, tmp_path, capsys):
    assert cli.COMMANDS["calibration"][0] == "gentlerl.apps.calibration"
    out = tmp_path / "calib.json"
    report = calibration_main([str(hand_run), "--episodes", "2", "--json", str(out)])
    text = capsys.readouterr().out
    assert json.loads(out.read_text()) == json.loads(json.dumps(report))
    assert report["frames"] == 300 and report["intrinsic_on"] is True
    assert report["variant"] == "r+rf+rsp" and report["gamma"] == 0.99
    assert report["not_saved"] == [] and "warning" not in text
    # the critic's own supports, one per head (the penalty is never positive)
    assert list(report["supports"]) == ["reward", "penalty", "penalty_surprise"]
    assert report["supports"]["penalty"][1] == 0.0
    for mode in ("deterministic", "noisy"):
        assert set(report["modes"][mode]) == {"reward", "penalty", "penalty_surprise"}
        for head in ("reward", "penalty", "penalty_surprise"):
            assert f"{head:<18} {mode:<13} start" in text
    assert report["seed"] == 0 and set(report["modes"]) == {"deterministic", "noisy"}
    # The noisy actions are not the actor's: the critic is read at other actions.
    predicted = [report["modes"][m]["reward"]["all"]["predicted"] for m in report["modes"]]
    assert predicted[0] != predicted[1]
    # Where the penalty surprise of contact steps comes from, per mode: its parts add up.
    for mode, x in report["penalty_surprise_sources"].items():
        assert 0 < x["contact_steps"] <= x["steps"]
        assert x["r_sp"] == pytest.approx(x["curiosity"] + x["refund"], rel=1e-4)
        assert x["nll"] == pytest.approx(x["spread"] + x["error"], rel=1e-5)
        assert x["z2"] == pytest.approx(2 * x["error"]) and x["refund"] > 0
        assert x["z2_all_steps"] > 0 and x["spread_all_steps"] is not None
        assert f"penalty surprise, {mode}: {x['contact_steps']} contact steps" in text
    assert set(report["penalty_surprise_sources"]) == {"deterministic", "noisy"}


def test_penalty_surprise_sources_need_a_penalty_surprise_and_contact():
    env = TransformedEnv(ToyHandEnv(), ImpactPenalty())
    episodes = rollout_episodes(env, None, 1, 5)
    assert penalty_surprise_sources(ImpactPenalty(), episodes) is None
    # Steps without contact: nothing to decompose, and None (not NaN) where a mean has no steps.
    stack = make_reward_transforms("r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3)
    stack.step(0)
    steps = pressing_rollout(ToyHandEnv())
    quiet = steps[(stack.transform(steps.clone())["next", keys.PENALTY] == 0).reshape(-1)]
    stats = penalty_surprise_sources(stack.transform, [quiet])
    assert stats["contact_steps"] == 0 and stats["steps"] == quiet.shape[0] > 0
    assert stats["r_sp"] is None and stats["penalty_std"] is None
    assert math.isfinite(stats["z2_all_steps"])  # every step still has a z-score
    json.dumps(stats, allow_nan=False)
    assert "no contact" in _sources_line("noisy", stats, {"intrinsic_on": True})
    # With contact, the line names what the curiosity read.
    touching = penalty_surprise_sources(stack.transform, [steps])
    for kind, reads in (("nll", "a's*nll"), ("information_gain", "a's*I")):
        line = _sources_line("noisy", touching, {"intrinsic_on": True, "surprise_kind": kind})
        assert f"curiosity {reads} " in line


def test_calibration_command_reproduces_the_runs_logged_scalars(hand_run):
    # The run evaluated once, at 300 frames, on 2 hands seeded with seed + 10000 = 10003: the
    # command's deterministic episodes with that seed are those episodes, and its numbers theirs.
    report = calibration_main(
        [str(hand_run / "checkpoint.pt"), "--episodes", "2", "--seed", "10003"]
    )
    logged = calibration_scalars(report["modes"]["deterministic"])
    sources = report["penalty_surprise_sources"]["deterministic"]
    assert sources["contact_steps"] > 0
    logged |= {f"surprise_sources/{k}": sources[k] for k in SOURCE_SCALARS}
    for name, value in logged.items():
        assert read_scalar(hand_run, name) == [(300, pytest.approx(value, abs=1e-4))], name


@pytest.mark.parametrize("target", ["missing", "best_policy.pt", "garbage.pt", "foreign.pt"])
def test_calibration_command_refuses_bad_input_in_one_line(hand_run, tmp_path, target):
    if target == "missing":
        path = tmp_path / "nowhere"
    elif target == "garbage.pt":
        path = tmp_path / target
        path.write_bytes(b"not a checkpoint")
    elif target == "foreign.pt":
        path = tmp_path / target
        save_checkpoint(path, {"weights": torch.zeros(3)})
    else:
        path = hand_run / target
    with pytest.raises(SystemExit) as err:
        calibration_main([str(path)])
    message = str(err.value.code)
    assert message.startswith("gentlerl calibration: error: ") and "\n" not in message
    if target == "best_policy.pt":
        assert "actor only" in message


def test_calibration_command_refuses_a_checkpoint_of_another_agent(hand_run, tmp_path):
    from gentlerl.training.checkpoint import load_checkpoint

    state = load_checkpoint(hand_run / "checkpoint.pt")
    state["config"]["network"]["num_atoms"] = 7  # the saved critic has 11 atoms
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    with pytest.raises(SystemExit, match="does not match this gentlerl's agent"):
        calibration_main([str(tmp_path), "--episodes", "1"])


def test_calibration_command_warns_of_config_fields_the_checkpoint_lacks(
    hand_run, tmp_path, capsys
):
    from gentlerl.training.checkpoint import load_checkpoint

    state = load_checkpoint(hand_run / "checkpoint.pt")
    del state["config"]["network"]["bounded_support"]  # as if saved before the field existed
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    report = calibration_main([str(tmp_path), "--episodes", "1"])
    assert report["not_saved"] == ["network.bounded_support"]
    assert "warning: the checkpoint predates config fields ['network.bounded_support']" in (
        capsys.readouterr().out
    )
