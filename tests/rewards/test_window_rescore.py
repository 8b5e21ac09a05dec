"""WindowRescorer: S seeds' windows re-scored for r^sp (one vmapped forward, or seed by seed on
a CPU) equal S calls of IntrinsicRewards.rescore_windows, each seed under its own target model."""

import re

import pytest
import torch

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.data import NStepWriter, make_replay_buffer
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.window_rescore import WindowRescorer
from tests.data.test_windows import _trajectory

SEEDS = (0, 1, 2)
OBS, ACT = 4, 2


def _rewards(seed, **settings):
    options = {"reward_delay": 0, "model_hidden": 16, "ensemble_size": 3, **settings}
    rewards = IntrinsicRewards(
        "r+rf+rsp", GentlenessConfig(**options), obs_dim=OBS, action_dim=ACT,
        feature_shapes={}, seed=seed,
    )  # fmt: skip
    rewards.step(0)
    return rewards


def _batch(rewards, seed):
    """A seed's 9 stored 3-step transitions with their windows (its own observations)."""
    data = _trajectory(obs_dim=OBS, act_dim=ACT)
    g = torch.Generator().manual_seed(seed)
    data["observation"] += torch.randn(data["observation"].shape, generator=g)
    rb = make_replay_buffer(100, 4, prioritized=False, n_steps=None)
    stored = ["reward", keys.PENALTY, keys.PENALTY_SURPRISE]
    writer = NStepWriter(rb, 3, 0.9, stored, rewards.window_keys)
    writer.extend(rewards.rescored[0](data))
    return rb[:]


def _both(**settings):
    """Each seed's rescore_windows and the batched rescoring, on equal models and batches."""
    singles = [_rewards(s, **settings) for s in SEEDS]
    grouped = [_rewards(s, **settings) for s in SEEDS]
    batches = [_batch(r, s) for r, s in zip(singles, SEEDS, strict=True)]
    for r, s in zip(grouped, SEEDS, strict=True):
        _batch(r, s)  # the same collection: a running curiosity scale folds it in too
    return singles, grouped, batches


@pytest.mark.parametrize("vmapped", [True, False], ids=["vmapped", "seed_by_seed"])
@pytest.mark.parametrize(
    "settings",
    [{}, {"curiosity_norm": True}, {"surprise_kind": "information_gain"}],
    ids=["paper", "curiosity_norm", "information_gain"],
)
def test_the_batched_rescoring_equals_each_seeds_own(settings, vmapped):
    singles, grouped, batches = _both(**settings)
    copies = [b.clone() for b in batches]
    expected = [r.rescore_windows(b, 0.9) for r, b in zip(singles, batches, strict=True)]
    stacked, got = WindowRescorer(grouped, vmapped=vmapped)(copies, 0.9)
    assert stacked.batch_size == (len(SEEDS), 9)
    for s in range(len(SEEDS)):
        torch.testing.assert_close(
            stacked[s]["next", keys.PENALTY_SURPRISE],
            batches[s]["next", keys.PENALTY_SURPRISE],
            rtol=1e-5,
            atol=1e-5,
        )
        key = "penalty_surprise_per_contact_step"
        assert got[s][key] == pytest.approx(expected[s][key], rel=1e-5)
    if settings.get("curiosity_norm"):  # each seed's running scale folded its own rows
        for single, group in zip(singles, grouped, strict=True):
            a, b = single.rescored[0].curiosity_scale, group.rescored[0].curiosity_scale
            assert b[1] == a[1] == 2 and b[0] == pytest.approx(a[0], rel=1e-5)


def test_a_target_copy_reaches_the_stack_and_the_gate_is_each_seeds():
    singles, grouped, batches = _both(penalty_target_period=1)
    rescore = WindowRescorer(grouped, vmapped=True)
    for r in (singles[1], grouped[1]):  # seed 1's model moves; its next update copies it
        with torch.no_grad():
            r.losses["penalty"].model_params.apply_(lambda p: p.add_(0.1))
        r.step(1)
    stacked, _ = rescore([b.clone() for b in batches], 0.9)
    singles[1].rescore_windows(batches[1], 0.9)
    torch.testing.assert_close(
        stacked[1]["next", keys.PENALTY_SURPRISE],
        batches[1]["next", keys.PENALTY_SURPRISE],
        rtol=1e-5,
        atol=1e-5,
    )
    grouped[2].rescored[0].active.fill_(False)  # a closed gate: that seed's r^sp is 0
    stacked, _ = rescore([b.clone() for b in batches], 0.9)
    assert (stacked[2]["next", keys.PENALTY_SURPRISE] == 0).all()
    assert (stacked[0]["next", keys.PENALTY_SURPRISE] != 0).any()


def test_a_batch_per_seed_is_needed_and_the_cpu_scores_seed_by_seed():
    grouped = [_rewards(s) for s in SEEDS]
    rescore = WindowRescorer(grouped)
    assert not rescore.vmapped and rescore.params == []  # CPU models: no stack, no shared rows
    with pytest.raises(ValueError, match=r"one batch per seed \(3\), got 1"):
        rescore([_batch(grouped[0], 0)], 0.9)
    other = [grouped[0], _rewards(1, lam_prime=(2.0, 3.0)), grouped[2]]
    with pytest.raises(ValueError, match=r"the rewards of seeds \[1\] differ from seed 0's"):
        WindowRescorer(other, vmapped=True)
    no_window = [_batch(r, s).exclude("window") for r, s in zip(grouped, SEEDS, strict=True)]
    with pytest.raises(KeyError, match="needs each transition's window of steps"):
        WindowRescorer(grouped, vmapped=True)(no_window, 0.9)


def test_one_seed_vmapped_equals_its_own_rescoring():
    single, grouped = _rewards(0), _rewards(0)
    batch = _batch(single, 0)
    expected = single.rescore_windows(batch, 0.9)
    stacked, (got,) = WindowRescorer([grouped], vmapped=True)([_batch(grouped, 0)], 0.9)
    torch.testing.assert_close(
        stacked[0]["next", keys.PENALTY_SURPRISE], batch["next", keys.PENALTY_SURPRISE]
    )
    assert got == pytest.approx(expected, rel=1e-5) and got


def _contacts(batch, steps: int):
    """``batch`` with a penalty (contact) at its first ``steps`` window steps only, in its
    first transitions' first steps (always counted: every window has at least one step)."""
    penalty = batch["window", "next", keys.PENALTY]
    penalty.zero_()
    penalty[:steps, 0] = -1.0
    return batch


@pytest.mark.parametrize("vmapped", [True, False], ids=["vmapped", "seed_by_seed"])
def test_a_seed_without_contact_has_no_per_contact_mean_and_one_with_one_has_its_value(vmapped):
    """Seed 0: no contact step, no ``_per_contact_step`` entry (no 0 / 0); seed 1: one contact
    step, whose rescored r^sp is the mean; seed 2: two."""
    grouped = [_rewards(s) for s in SEEDS]
    batches = [_contacts(_batch(r, s), s) for r, s in zip(grouped, SEEDS, strict=True)]
    stacked, metrics = WindowRescorer(grouped, vmapped=vmapped)(batches, 0.9)
    key = "penalty_surprise_per_contact_step"
    assert metrics[0] == {}
    assert (stacked[0]["next", keys.PENALTY_SURPRISE] == 0).all()  # r^sp needs a contact
    # seed 1's one contact step is transition 0's first: its n-step r^sp is that step's alone
    assert metrics[1][key] == pytest.approx(stacked[1]["next", keys.PENALTY_SURPRISE][0].item())
    assert metrics[1][key] != 0
    assert set(metrics[2]) == {key}


@pytest.mark.parametrize("vmapped", [True, False], ids=["vmapped", "seed_by_seed"])
def test_a_rescoring_counts_as_rescored_for_the_stale_surprise_guard(vmapped):
    """The group's scorer (vmapped, or each seed's rescore_windows) marks every seed's surprise
    rescored: their updates with the rewards on then run (without it the guard stops the
    second: never rescored)."""
    grouped = [_rewards(s, model_batch_size=4) for s in SEEDS]
    batches = [_batch(r, s) for r, s in zip(grouped, SEEDS, strict=True)]
    WindowRescorer(grouped, vmapped=vmapped)(batches, 0.9)
    for rewards in grouped:
        rewards.extend(rewards.rescored[0](_trajectory(obs_dim=OBS, act_dim=ACT)))
        for _ in range(3):
            rewards.update()
        assert rewards.intrinsic_on and rewards.num_updates == 3
    unmarked = _rewards(0, model_batch_size=4)
    unmarked.extend(unmarked.rescored[0](_trajectory(obs_dim=OBS, act_dim=ACT)))
    unmarked.update()
    message = (
        "rescore_surprise=True, but penalty surprise was never scored again at sampling: append "
        "rewards.rescore_transform() to the replay buffer (or call rescore_windows() on n-step "
        "batches), or set GentlenessConfig(rescore_surprise=False)"
    )
    with pytest.raises(RuntimeError, match=f"^{re.escape(message)}$"):
        unmarked.update()


def test_the_refusals_in_full():
    with pytest.raises(
        ValueError, match=r"^WindowRescorer needs at least one seed's rewards, got 0$"
    ):
        WindowRescorer([])
    grouped = [_rewards(s) for s in SEEDS]
    other = [grouped[0], _rewards(1, lam_prime=(2.0, 3.0)), _rewards(2, reward_delay=5)]
    with pytest.raises(ValueError) as refused:
        WindowRescorer(other)
    assert str(refused.value) == (
        "WindowRescorer: the rewards of seeds [1, 2] differ from seed 0's in their variant or "
        "gentleness settings; a group's seeds share both"
    )
    variant = IntrinsicRewards(
        "rf+rsp", GentlenessConfig(reward_delay=0, model_hidden=16, ensemble_size=3),
        obs_dim=OBS, action_dim=ACT, feature_shapes={},
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"the rewards of seeds \[1\] differ"):
        WindowRescorer([grouped[0], variant])
    rescore = WindowRescorer(grouped, vmapped=True)
    with pytest.raises(ValueError, match=r"^WindowRescorer needs one batch per seed \(3\), got 4$"):
        rescore([_batch(grouped[0], 0)] * 4, 0.9)


def test_without_rescored_rewards_nothing_is_stacked_and_the_batches_are_left_as_they_are():
    grouped = [_rewards(s, rescore_surprise=False) for s in SEEDS]
    for vmapped in (True, False):
        rescore = WindowRescorer(grouped, vmapped=vmapped)
        assert rescore.transforms == [] and rescore.params == []
        batches = [_batch(_rewards(s), s) for s in SEEDS]
        stored = [b["next", keys.PENALTY_SURPRISE].clone() for b in batches]
        stacked, metrics = rescore(batches, 0.9)
        assert metrics == [{}, {}, {}] and stacked.batch_size == (3, 9)
        for s in range(3):
            assert torch.equal(stacked[s]["next", keys.PENALTY_SURPRISE], stored[s])


def test_the_vmapped_stack_holds_each_seeds_target_rows_as_views():
    grouped = [_rewards(s) for s in SEEDS]
    rescore = WindowRescorer(grouped, vmapped=True)
    (seeds,) = rescore.transforms
    assert [t is r.rescored[0] for t, r in zip(seeds, grouped, strict=True)] == [True] * 3
    (stack,) = rescore.params
    for s, t in enumerate(seeds):
        for key, value in t.params.items(True, True):
            assert torch.equal(stack[key][s], value)
            assert value.data_ptr() == stack[key][s].data_ptr()  # a view of row s
