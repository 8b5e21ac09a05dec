"""Method III on the drop-in surface: the tolerance rule in ImpactPenalty, the normalised
curiosity in PenaltySurprise, the impact multiplier, the weighted actor objective, and a run
that steers and resumes its multiplier."""

import math

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.functional import gaussian_nll, mixture_moments
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.multiplier import ImpactMultiplier
from gentlerl.transforms import ImpactPenalty
from tests.helpers import pressing_rollout
from tests.toy_env import ToyHandEnv


def _press(newtons: float) -> TensorDict:
    nxt = torch.zeros(5, 3)
    nxt[0, 0] = newtons
    return TensorDict({keys.TOUCH: torch.zeros(5, 3), "next": {keys.TOUCH: nxt}})


@pytest.mark.parametrize("tolerance", [2.0, 20.0, 300.0])
def test_an_impact_at_the_tolerance_costs_minus_one_and_is_written_in_newtons(tolerance):
    out = IntrinsicRewards(
        "r+rf", GentlenessConfig(tolerance=tolerance), obs_dim=1, action_dim=1, feature_shapes={}
    ).transform[0](_press(tolerance))
    assert out["next", keys.IMPACT][0].item() == pytest.approx(tolerance)  # N, not units
    assert out["next", keys.PENALTY].item() == pytest.approx(-1.0)


def test_the_paper_hand_is_the_tolerance_rule_at_two_newtons():
    for newtons in (0.5, 1.0, 3.0, 7.0):
        paper = ImpactPenalty()(_press(newtons))["next", keys.PENALTY]
        ruled = ImpactPenalty(unit=1.0)(_press(newtons))["next", keys.PENALTY]
        assert torch.equal(paper, ruled)
    with pytest.raises(ValueError, match="unit must be a finite force > 0"):
        ImpactPenalty(unit=0.0)


def test_normalised_curiosity_is_the_nll_over_its_running_mean_on_contact_steps():
    settings = dict(model_hidden=16, ensemble_size=3, reward_delay=0)
    rewards = IntrinsicRewards.from_env(
        ToyHandEnv(), "r+rf+rsp", GentlenessConfig(curiosity_norm=True, **settings)
    )
    rewards.step(1)  # the rewards on
    rsp = rewards.transform[1]
    batch = pressing_rollout(ToyHandEnv())
    penalty = rewards.transform[0](batch.clone())["next", keys.PENALTY]
    contact = penalty.squeeze(-1) < 0
    assert contact.any() and not contact.all()
    mean, var = rsp.predict(batch[contact].select(keys.OBSERVATION, keys.ACTION))
    mu, sigma2 = mixture_moments(mean, var, dim=0)
    nll = gaussian_nll(penalty[contact], mu, sigma2)
    scored = rewards.transform(batch.clone())
    assert rsp.curiosity_scale == (pytest.approx(nll.abs().mean().item(), rel=1e-5), 1)
    a_prime = torch.sigmoid(2.0 * (2.0 + penalty[contact]))  # lam' = [2, 2] on |r^f|
    expected = a_prime * (nll / nll.abs().mean() - penalty[contact])
    torch.testing.assert_close(scored["next", keys.PENALTY_SURPRISE][contact], expected)
    # the scale is saved and restored with the rewards' state
    state = rewards.state_dict()
    again = IntrinsicRewards.from_env(
        ToyHandEnv(), "r+rf+rsp", GentlenessConfig(curiosity_norm=True, **settings)
    )
    again.load_state_dict(state)
    assert again.transform[1].curiosity_scale == rsp.curiosity_scale


def test_the_multiplier_by_hand():
    """T = 2 N, gains (1, 0.1, 0), window 2: each episode's cost is log2 of the window's median
    over T (floored at T/2), its limit 0."""
    m = ImpactMultiplier(2.0, (1.0, 0.1, 0.0), window=2)
    assert m.weight == 1.0  # the paper until an episode ends
    e = math.log2(3.0)  # median 6 N: 3 tolerances
    assert m.observe([6.0]) == pytest.approx(1.0 + e + 0.1 * e)
    integral = 0.1 * e + 0.1 * 1.0  # median(6, 2) = 4 N: one doubling
    assert m.observe([2.0]) == pytest.approx(1.0 + 1.0 + integral)
    # median(2, 1) = 1.5 N: e = log2(0.75), mu = max(0, e + I) = 0; then median(1, 1) = 1 N,
    # the floor T/2: e = -1
    integral += 0.1 * math.log2(0.75) - 0.1
    assert m.observe([1.0, 1.0]) == 1.0
    assert m.integral == pytest.approx(integral) and m.scalars()["impact_cost"] == -1.0
    restored = ImpactMultiplier(2.0, (1.0, 0.1, 0.0), window=2)
    restored.load_state_dict(m.state_dict())
    assert restored.observe([8.0]) == m.observe([8.0])
    with pytest.raises(ValueError, match="finite and >= 0"):
        m.observe([math.nan])


def test_a_multiplier_with_a_period_steps_once_per_period_of_env_steps():
    """period 1000: the first call only notes the frame count; then one PID step per multiple
    of 1000 passed (however many episodes ended), on the window's median; capped integral."""
    m = ImpactMultiplier(2.0, (1.0, 0.1, 0.0), window=3, period=1000, integral_max=0.15)
    assert m.observe([8.0, 8.0], frames=5200) == 1.0 and m.steps == 0  # the start: no step
    assert m.observe([8.0] * 5, frames=5800) == 1.0 and m.steps == 0  # no multiple passed
    # 6000 passed: one step on median(8, 8, 8) = 8 N, two doublings: I = 0.2 capped at 0.15
    assert m.observe([], frames=6000) == pytest.approx(1.0 + 2.0 + 0.15)
    assert (m.steps, m.episodes, m.integral) == (1, 7, 0.15)
    # a call that passes two multiples steps twice (here: no episode ended meanwhile)
    m.observe([], frames=8100)
    assert m.steps == 3 and m.integral == 0.15
    # gentle episodes: median(8, 1, 1) = 1 N, e = -1: I = 0.05, mu = max(0, -1 + 0.05) = 0
    assert m.observe([1.0, 1.0], frames=9000) == 1.0 and m.integral == pytest.approx(0.05)
    restored = ImpactMultiplier(2.0, (1.0, 0.1, 0.0), window=3, period=1000, integral_max=0.15)
    restored.load_state_dict(m.state_dict())
    assert restored.observe([9.0], frames=10_000) == m.observe([9.0], frames=10_000)
    with pytest.raises(ValueError, match="pass frames"):
        m.observe([1.0])
    # a state saved before the period existed: one step per episode, no frames seen
    old = {k: v for k, v in m.state_dict().items() if k not in ("steps", "frames")}
    restored.load_state_dict(old)
    assert (restored.steps, restored.frames) == (m.episodes, -1)


def test_a_plain_lagrangian_starts_at_no_penalty_and_says_when_it_is_due():
    """base 0: w = mu, so 0 until a PID step sees the cost above its limit; due(frames) says
    whether observe(frames) would step (a multiple of the period passed since the last call)."""
    m = ImpactMultiplier(2.0, (1.0, 0.1, 0.0), window=2, period=1000, base=0.0)
    assert m.weight == 0.0 and not m.due(5200)  # no frames seen yet: the start only notes them
    m.observe([], frames=5200)
    assert not m.due(5999) and m.due(6000)
    # median(6, 1) = 3.5 N: e = log2(1.75), I = 0.1 e, w = 0 + e + I
    e = math.log2(1.75)
    assert m.observe([6.0, 1.0], frames=6000) == pytest.approx(1.1 * e)
    # median(1, 1) = 1 N, the floor: e = -1, mu = max(0, -1 + I) = 0: no penalty at all
    assert m.observe([1.0, 1.0], frames=7000) == 0.0
    with pytest.raises(ValueError, match="due\\(\\) needs a period"):
        ImpactMultiplier(2.0, (1.0, 0.1, 0.0)).due(1000)
    with pytest.raises(ValueError, match="base must be a finite weight >= 0, got -1.0"):
        ImpactMultiplier(2.0, (1.0, 0.1, 0.0), base=-1.0)


def test_a_loop_of_ones_own_steps_the_multiplier_from_its_collector_batches():
    """observe_batch: each episode's max impact over sites and steps, told by the collector's
    trajectory ids; an episode running into the next batch carries its max."""
    from tensordict import TensorDict

    def batch(traj, done, impacts):  # impacts [T, 2 sites]
        n = len(traj)
        nxt = {keys.IMPACT: torch.tensor(impacts), keys.DONE: torch.tensor(done).view(n, 1)}
        return TensorDict(
            {"collector": {"traj_ids": torch.tensor(traj)}, "next": nxt}, batch_size=[n]
        )

    m = ImpactMultiplier(2.0, (1.0, 0.0, 0.0), window=1)
    first = batch([0, 0, 0, 1, 1], [False, False, True, False, False],
                  [[1.0, 6.0], [0.0, 2.0], [1.0, 0.0], [8.0, 0.0], [0.0, 1.0]])  # fmt: skip
    # episode 0 ends at 6 N (log2(3) doublings above T); episode 1 runs on at 8 N so far
    assert m.observe_batch(first) == pytest.approx(1.0 + math.log2(3.0))
    assert m.episodes == 1
    second = batch([1, 2], [True, False], [[0.5, 0.5], [3.0, 3.0]])
    # episode 1 ends: its max over both batches is 8 N, two doublings
    assert m.observe_batch(second) == pytest.approx(3.0) and m.episodes == 2


def test_the_actor_maximises_the_weighted_sum_of_its_heads():
    from tests.agent.test_learner import _batch, _learner  # a 2-head D4PG loss and its batch

    loss, batch = _learner().loss, _batch()
    plain = loss(batch.clone())
    loss.set_head_weight("penalty", 3.0)
    weighted = loss(batch.clone())["loss_actor"]
    # -(Q_r + 3 Q_f) = -(Q_r + Q_f) - 2 Q_f, Q_f averaged over the batch as the loss is
    expected = plain["loss_actor"] - 2.0 * plain["value_penalty"]
    torch.testing.assert_close(weighted, expected, rtol=1e-5, atol=1e-5)
    assert loss.head_weights.tolist() == [1.0, 3.0]


@pytest.mark.parametrize("period", [None, 100])
def test_a_run_steers_the_penalty_head_logs_the_multiplier_and_resumes_it(tmp_path, period):
    """multiplier=pid on the toy hand (episodes of 50 steps, impacts of 2 N per pressing step
    against a tolerance of 0.5 N): the weight rises above 1, the actor's objective carries it,
    it is logged, and a resumed run restores it before its first update. With a period, one PID
    step per 100 env steps of learning."""
    from gentlerl.training import Trainer
    from tests.helpers import read_scalar, tiny_config, toy_env

    gentle = dict(tolerance=0.5, multiplier="pid", reward_delay=100, model_hidden=16)
    gentle["multiplier_period"] = period
    cfg = tiny_config(tmp_path / "run", variant="r+rf", total_frames=900, gentleness=gentle)
    trainer = Trainer(cfg, toy_env)
    trainer.run()
    multiplier = trainer.rewards.multiplier
    assert multiplier.episodes >= 10 and multiplier.weight > 1.0
    if period is not None:  # stepped from the first learning batch on, once per 100 steps
        first = trainer.cfg.collector.init_random_frames
        assert multiplier.steps in range((900 - first) // period - 2, (900 - first) // period + 1)
    assert trainer.learner.loss.head_weights.tolist() == [1.0, pytest.approx(multiplier.weight)]
    logged = read_scalar(tmp_path / "run", "train/penalty_weight")
    assert logged and logged[-1][1] == pytest.approx(multiplier.weight)
    longer = tiny_config(
        tmp_path / "run", variant="r+rf", total_frames=1000, gentleness=gentle, resume=True
    )
    resumed = Trainer(longer, toy_env)
    resumed._resume()
    assert resumed.rewards.multiplier.state_dict() == multiplier.state_dict()
    assert resumed.learner.loss.head_weights[1].item() == pytest.approx(multiplier.weight)


def test_a_run_can_steer_on_the_deployed_policys_noise_free_episodes(tmp_path):
    """multiplier_episodes=2, period 100, base 0: the penalty head's weight starts at 0 (w_0),
    and each PID step reads two noise-free episodes of the current actor, not the collection's
    (about 16 collection episodes of 50 steps end in this run's learning frames)."""
    from gentlerl.training import Trainer
    from tests.helpers import tiny_config, toy_env

    gentle = dict(tolerance=0.5, multiplier="pid", reward_delay=100, model_hidden=16)
    gentle.update(multiplier_period=100, multiplier_episodes=2, multiplier_base=0.0)
    cfg = tiny_config(tmp_path / "run", variant="r+rf", total_frames=900, gentleness=gentle)
    trainer = Trainer(cfg, toy_env)
    assert trainer.learner.loss.head_weights.tolist() == [1.0, 0.0]
    trainer.run()
    multiplier = trainer.rewards.multiplier
    first = trainer.cfg.collector.init_random_frames
    assert multiplier.steps in range((900 - first) // 100 - 2, (900 - first) // 100 + 1)
    assert multiplier.steps >= 3 and multiplier.episodes == 2 * multiplier.steps
    assert trainer.learner.loss.head_weights[1].item() == pytest.approx(multiplier.weight)


def test_a_multiplier_without_a_penalty_head_or_a_tolerance_is_refused_up_front(tmp_path):
    from tests.helpers import tiny_config

    with pytest.raises(ValueError, match="weighs the penalty head, which variant=r lacks"):
        tiny_config(tmp_path, variant="r", gentleness=dict(tolerance=1.0, multiplier="pid"))
    with pytest.raises(ValueError, match="set gentleness.tolerance"):
        tiny_config(tmp_path, variant="r+rf", gentleness=dict(multiplier="pid"))
    with pytest.raises(ValueError, match="multiplier_period=1000 applies to gentleness.multip"):
        tiny_config(tmp_path, variant="r+rf", gentleness=dict(multiplier_period=1000))
    with pytest.raises(ValueError, match="multiplier_base=0.0 applies to gentleness.multiplier"):
        tiny_config(tmp_path, variant="r+rf", gentleness=dict(multiplier_base=0.0))
    steered = dict(tolerance=1.0, multiplier="pid", multiplier_episodes=3)
    with pytest.raises(ValueError, match="multiplier_episodes=3 runs at each PID step: set gen"):
        tiny_config(tmp_path, variant="r+rf", gentleness=steered)


def test_a_single_critic_agent_puts_the_multiplier_on_its_summed_penalty():
    from gentlerl.rewards import SumRewards

    td = TensorDict({"next": {"reward": torch.ones(1), "penalty": -0.5 * torch.ones(1)}})
    reward_sum = SumRewards(["reward", "penalty"])
    reward_sum.set_weight("penalty", ImpactMultiplier(2.0, (1.0, 0.0, 0.0)).observe([8.0]))
    assert reward_sum(td)["next", "reward"].item() == pytest.approx(1.0 - 0.5 * 3.0)  # w = 1 + 2
    with pytest.raises(KeyError, match="not one of the summed keys"):
        reward_sum.set_weight("penalty_surprise", 1.0)


def test_the_curiosity_scale_is_shared_by_clones_and_frozen_while_evaluating():
    """An env's clone of the transforms learns the same running scale the rewards checkpoint;
    scoring under frozen_scale (evaluations, calibration) leaves it as it was."""
    from gentlerl.transforms.surprise import frozen_scale

    settings = GentlenessConfig(curiosity_norm=True, model_hidden=16, reward_delay=0)
    rewards = IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", settings)
    rewards.step(1)
    clone = rewards.transform.clone()
    clone(pressing_rollout(ToyHandEnv()))
    learned = rewards.transform[1].curiosity_scale
    assert learned[1] == 1 and learned[0] > 0  # learned through the clone, seen by the original
    with frozen_scale(rewards.transform):
        rewards.transform(pressing_rollout(ToyHandEnv()))
    assert rewards.transform[1].curiosity_scale == learned
    assert rewards.transform[1].learn_scale  # switched back on


def test_a_head_weight_for_a_head_the_loss_lacks_is_refused_naming_the_heads():
    from tests.agent.test_learner import _learner

    with pytest.raises(KeyError, match="'penalty_surprise' is not one of the heads"):
        _learner().loss.set_head_weight("penalty_surprise", 2.0)
