"""``ImpactMultiplier`` (gentlerl.rewards.multiplier) against hostile input: a NaN impact in a
collector's batch, a tampered saved state, non-finite or boolean settings; each refused in one
line naming the value (its steering by hand: tests/rewards/test_tolerance.py)."""

import math

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.rewards.multiplier import ImpactMultiplier


def _batch(impacts: list[float], done_at_end: bool = True) -> TensorDict:
    """One trajectory of ``len(impacts)`` steps, one site each, done at its last step."""
    n = len(impacts)
    done = torch.zeros(n, 1, dtype=torch.bool)
    done[-1] = done_at_end
    return TensorDict(
        {
            ("collector", "traj_ids"): torch.zeros(n, dtype=torch.int64),
            ("next", keys.IMPACT): torch.tensor(impacts).reshape(n, 1),
            ("next", keys.DONE): done,
        },
        batch_size=[n],
    )


def test_a_nan_impact_beside_a_9_newton_peak_is_refused_not_read_as_0_newtons():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0))
    with pytest.raises(ValueError, match=r"non-finite impact at 1 of 3 steps"):
        multiplier.observe_batch(_batch([9.0, math.nan, 0.5]))
    assert multiplier.episodes == 0 and multiplier.weight == 1.0  # nothing observed


def test_a_nan_impact_in_an_episode_that_goes_on_is_refused_too():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0))
    with pytest.raises(ValueError, match="non-finite impact"):
        multiplier.observe_batch(_batch([math.nan, 9.0], done_at_end=False))
    assert multiplier.observe_batch(_batch([9.0, 1.0])) > 1.0  # a finite batch steers


def _state(**changes):
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0), integral_max=5.0)
    multiplier.observe([4.0, 3.0])
    return multiplier, {**multiplier.state_dict(), **changes}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"recent": [1.0, math.nan]}, r"'recent'=\[1.0, nan\] must be a list of finite impacts >= 0"),
        ({"recent": [-1.0]}, r"'recent'=\[-1.0\] must be a list of finite impacts >= 0"),
        ({"recent": "4.0"}, r"'recent'='4.0' must be a list of finite impacts >= 0"),
        ({"multiplier": math.inf}, "'multiplier'=inf must be a finite number >= 0"),
        ({"multiplier": -1.0}, "'multiplier'=-1.0 must be a finite number >= 0"),
        ({"integral": math.nan}, r"'integral'=nan must be a finite number in \[0, 5.0\]"),
        ({"integral": 6.0}, r"'integral'=6.0 must be a finite number in \[0, 5.0\]"),
        ({"cost": math.nan}, "'cost'=nan must be a finite number"),
        ({"cost": True}, "'cost'=True must be a finite number"),
        ({"episodes": -1}, "'episodes'=-1 must be an integer >= 0"),
        ({"episodes": 2.5}, "'episodes'=2.5 must be an integer >= 0"),
        ({"steps": True}, "'steps'=True must be an integer >= 0"),
        ({"frames": -2}, "'frames'=-2 must be an integer >= -1"),
        ({"multiplier": None}, "'multiplier'=None must be a finite number >= 0"),
    ],
)  # fmt: skip
def test_a_tampered_state_is_refused_naming_the_entry_and_leaves_the_multiplier_as_it_was(
    changes, message
):
    multiplier, state = _state(**changes)
    before = multiplier.state_dict()
    with pytest.raises(ValueError, match=r"ImpactMultiplier state " + message):
        multiplier.load_state_dict(state)
    assert multiplier.state_dict() == before


def test_a_state_missing_an_entry_is_refused_naming_it():
    multiplier, state = _state()
    del state["integral"]
    with pytest.raises(ValueError, match="ImpactMultiplier state lacks 'integral'"):
        multiplier.load_state_dict(state)


def test_a_saved_state_loads_back_unchanged():
    multiplier, state = _state()
    again = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0), integral_max=5.0)
    again.load_state_dict(state)
    assert again.state_dict() == state and again.weight == multiplier.weight


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"gains": (math.nan, 0.1, 0.0)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"gains": (1.0, math.inf, 0.0)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"gains": (1.0, 0.1, True)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"tolerance": True}, "tolerance must be a finite impact > 0, got True"),
        ({"window": True}, "window must be an integer >= 1 episode, got True"),
        ({"window": 2.5}, "window must be an integer >= 1 episode, got 2.5"),
        ({"period": True}, r"period must be an integer >= 1 env step \(or None\), got True"),
        ({"period": 0.5}, r"period must be an integer >= 1 env step \(or None\), got 0.5"),
        ({"integral_max": math.nan}, r"integral_max must be a number >= 0 \(or None\), got nan"),
        ({"base": True}, "base must be a finite weight >= 0, got True"),
    ],
)  # fmt: skip
def test_non_finite_or_boolean_settings_are_refused_at_construction(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ImpactMultiplier(**{"tolerance": 2.0, "gains": (1.0, 0.1, 0.0), **kwargs})


def _sites(impacts: list[list[float]], traj: int = 0, done_at_end: bool = True) -> TensorDict:
    """One trajectory's steps, ``impacts[t]`` the impact of each site at step t."""
    batch = _batch([0.0] * len(impacts), done_at_end)
    batch["next", keys.IMPACT] = torch.tensor(impacts)
    batch["collector", "traj_ids"] = torch.full((len(impacts),), traj)
    return batch


def test_the_non_finite_impacts_are_counted_by_step_and_the_first_is_shown():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0))
    batch = _sites([[0.5, math.nan], [0.5, 0.5], [math.inf, math.nan]])
    with pytest.raises(ValueError) as refused:
        multiplier.observe_batch(batch)
    assert str(refused.value) == (
        "(\"next\", 'impact') holds a non-finite impact at 2 of 3 steps (first: [0.5, nan]): "
        "the episodes' max impact needs finite impacts"
    )


def test_an_episodes_max_impact_is_over_its_sites_and_steps_and_carries_across_batches():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0))
    multiplier.observe_batch(_sites([[0.125, 0.375], [0.25, 0.125]]))  # a light one: 0.375 N
    assert list(multiplier.recent) == [0.375]
    multiplier.observe_batch(_sites([[0.625, 0.0]], traj=1, done_at_end=False))  # goes on
    assert list(multiplier.recent) == [0.375] and multiplier.episodes == 1
    multiplier.observe_batch(_sites([[0.125, 0.25]], traj=1))  # ends: its max was 0.625 N
    assert list(multiplier.recent) == [0.375, 0.625] and multiplier.episodes == 2


def test_observe_batch_with_a_period_steps_on_the_frames_it_is_given():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.0, 0.0), period=10)
    assert multiplier.observe_batch(_sites([[8.0]]), frames=10) == 1.0  # the first call: no step
    assert multiplier.frames == 10 and multiplier.steps == 0
    # 8 N at a 2 N tolerance: two doublings over it, K_P = 1: mu = 2
    assert multiplier.observe_batch(_sites([[8.0]], traj=1), frames=25) == pytest.approx(3.0)
    assert multiplier.frames == 25 and multiplier.steps == 1


def test_due_is_true_once_a_period_has_passed_since_the_last_frames_seen_even_from_frame_0():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0), period=10)
    assert not multiplier.due(100)  # no frames seen yet: the first observe only notes them
    multiplier.observe([], frames=0)
    assert not multiplier.due(9) and multiplier.due(10)
    multiplier.observe([], frames=15)
    assert not multiplier.due(19) and multiplier.due(20)
    with pytest.raises(
        ValueError, match=r"^due\(\) needs a period: without one the PID steps per episode$"
    ):
        ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0)).due(10)


def test_a_fresh_state_and_one_at_the_bounds_of_each_entry_load():
    fresh = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0), integral_max=5.0)
    state = fresh.state_dict()  # no episode, no step, no frames
    assert state["episodes"] == state["steps"] == 0 and state["frames"] == -1
    again = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0), integral_max=5.0)
    again.load_state_dict(state)
    assert again.state_dict() == state
    bounds = {**state, "recent": [0.0, 0.5], "integral": 5.0, "multiplier": 0.0, "frames": 0}
    again.load_state_dict(bounds)
    assert again.state_dict() == bounds


def test_the_smallest_settings_are_accepted_and_the_next_ones_down_refused():
    smallest = ImpactMultiplier(
        tolerance=0.5, gains=(1.0, 0.1, 0.0), window=1, period=1, integral_max=0.0, base=0.0
    )
    assert (smallest.tolerance, smallest.period, smallest.integral_max, smallest.base) == (
        0.5, 1, 0.0, 0.0,
    )  # fmt: skip
    smallest.observe([1.0, 2.0, 3.0], frames=1)
    assert list(smallest.recent) == [3.0]  # a window of one episode
    refused = [
        ({"tolerance": 0.0}, "tolerance must be a finite impact > 0, got 0.0"),
        ({"window": 0}, "window must be an integer >= 1 episode, got 0"),
        ({"period": 0}, r"period must be an integer >= 1 env step \(or None\), got 0"),
        ({"integral_max": -0.5}, r"integral_max must be a number >= 0 \(or None\), got -0.5"),
        ({"base": -0.5}, "base must be a finite weight >= 0, got -0.5"),
    ]
    for kwargs, message in refused:
        with pytest.raises(ValueError, match=f"^{message}$"):
            ImpactMultiplier(**{"tolerance": 2.0, "gains": (1.0, 0.1, 0.0), **kwargs})


def test_the_window_keeps_the_last_ten_episodes_and_a_gentle_one_counts():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.1, 0.0))
    multiplier.observe([float(i) for i in range(12)])
    assert list(multiplier.recent) == [float(i) for i in range(2, 12)]
    assert multiplier.episodes == 12
    multiplier.observe([0.0])  # no contact at all: an impact of 0 is an episode too
    assert multiplier.recent[-1] == 0.0 and multiplier.episodes == 13
    with pytest.raises(
        ValueError, match=r"^an episode's max impact must be finite and >= 0, got nan$"
    ):
        multiplier.observe([math.nan])


def test_the_derivative_acts_from_the_second_step_on_a_rising_cost():
    """K_D alone: the first step has no previous cost (no kick from 0); the second sees the
    median of 8 N and 32 N, 20 N = log2(10) doublings, up from 2: mu = log2(10) - 2."""
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(0.0, 0.0, 1.0))
    assert multiplier.observe([8.0]) == 1.0 and multiplier.cost == 2.0
    assert multiplier.observe([32.0]) == pytest.approx(1.0 + math.log2(10.0) - 2.0)


def test_a_period_counts_from_frame_0_and_needs_frames():
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(1.0, 0.0, 0.0), period=10)
    assert multiplier.observe([8.0], frames=0) == 1.0 and multiplier.steps == 0
    assert multiplier.observe([8.0], frames=10) == pytest.approx(3.0)  # 2 doublings, K_P = 1
    assert multiplier.steps == 1
    with pytest.raises(ValueError, match=r"^period=10 steps on env steps: pass frames$"):
        multiplier.observe([8.0])


def test_the_integral_is_capped_the_steps_counted_and_the_scalars_named():
    """K_I alone at 8 N (2 doublings over 2 N): the integral would reach 2, 4, ... but stops at
    integral_max = 1.5, so mu = 1.5."""
    multiplier = ImpactMultiplier(tolerance=2.0, gains=(0.0, 1.0, 0.0), integral_max=1.5)
    for _ in range(3):
        multiplier.observe([8.0])
    assert multiplier.steps == 3 and multiplier.integral == 1.5
    assert multiplier.scalars() == {
        "penalty_weight": 2.5, "multiplier_integral": 1.5, "impact_cost": 2.0,
    }  # fmt: skip
