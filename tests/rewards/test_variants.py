"""The variants registry: reward components, head order, supports, curiosity heads."""

import pytest

from gentlerl import keys
from gentlerl.rewards.variants import (
    COMPONENTS,
    VARIANTS,
    critic_supports,
    discounted_horizon,
    head_supports,
    intrinsic_keys,
    reward_keys,
)


def test_every_variant_names_registered_components():
    for name, components in VARIANTS.items():
        assert components and all(k in COMPONENTS for k in components), name
    # The paper's method: task reward, impact penalty, penalty surprise, in that head order.
    assert reward_keys("r+rf+rsp") == [keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE]


def test_unknown_variant_is_a_clear_error():
    with pytest.raises(ValueError, match=r"unknown variant 'r\+x'; expected one of \["):
        reward_keys("r+x")


def test_only_curiosity_rewards_are_intrinsic():
    assert intrinsic_keys(reward_keys("r+rf+rs")) == [keys.DYNAMICS_SURPRISE]
    assert intrinsic_keys(reward_keys("r+icm")) == [keys.ICM_REWARD]
    assert intrinsic_keys(reward_keys("r+rf")) == []


def test_bounded_support_caps_never_positive_rewards_at_zero():
    heads = reward_keys("r+rf+rsp")

    def tops(v_max, bounded):
        return head_supports(heads, v_min=-10.0, v_max=v_max, bounded=bounded)[1]

    assert tops(10.0, bounded=True) == [10.0, 0.0, 10.0]
    assert tops(10.0, bounded=False) == [10.0, 10.0, 10.0]
    assert tops(-1.0, bounded=True) == [-1.0, -1.0, -1.0]  # never above v_max


def test_discounted_horizon_is_the_geometric_sum():
    # (1 - 0.99^200) / (1 - 0.99) = 86.60 (touch's 200 steps at the default gamma)
    assert discounted_horizon(0.99, 200) == pytest.approx(86.6020, abs=1e-4)
    assert discounted_horizon(0.5, 3) == pytest.approx(1 + 0.5 + 0.25)
    assert discounted_horizon(1.0, 7) == 7.0
    with pytest.raises(ValueError, match="gamma"):
        discounted_horizon(1.5, 10)


def test_dense_heads_get_a_horizon_wide_support_the_task_keeps_its_own():
    heads = reward_keys("r+rf+rsp")  # task (terminal), penalty (dense, <= 0), rsp (dense)
    lows, highs = head_supports(heads, v_min=-10.0, v_max=10.0, bounded=True, dense_span=86.6)
    assert lows == [-10.0, -86.6, -86.6]
    assert highs == [10.0, 0.0, 86.6]
    # null span: one shared support (the paper's (-100, 100) as published)
    lows, highs = head_supports(heads, v_min=-100.0, v_max=100.0, bounded=False)
    assert lows == [-100.0] * 3 and highs == [100.0] * 3
    with pytest.raises(ValueError, match="dense_span"):
        head_supports(heads, v_min=-1.0, v_max=1.0, bounded=False, dense_span=0.0)


def test_a_head_named_in_spans_gets_its_own_the_others_keep_the_dense_one():
    heads = reward_keys("r+rf+rsp")
    spans = {keys.PENALTY_SURPRISE: 259.8}
    lows, highs = head_supports(
        heads, v_min=-10.0, v_max=10.0, bounded=True, dense_span=86.6, spans=spans
    )
    assert lows == [-10.0, -86.6, -259.8] and highs == [10.0, 0.0, 259.8]
    for bad in ({keys.PENALTY_SURPRISE: -1.0}, {"bonus": 1.0}):
        with pytest.raises(ValueError, match="spans must map"):
            head_supports(heads, v_min=-1.0, v_max=1.0, bounded=False, spans=bad)


def test_learned_components_name_their_model():
    built = {k: c.model for k, c in COMPONENTS.items() if c.build is not None}
    assert built == {
        keys.DYNAMICS_SURPRISE: "dynamics",
        keys.PENALTY_SURPRISE: "penalty",
        keys.ICM_REWARD: "icm",
        keys.FORCE_PENALTY: None,  # the wear penalties have a transform but no model
        keys.TORQUE_PENALTY: None,
        keys.EXCESS_PENALTY: None,  # Method IV's cost: a transform, no model
    }


def test_the_bounds_of_gamma_and_of_the_spans():
    assert discounted_horizon(0.0, 5) == 1.0  # gamma 0: the first step's reward only
    assert discounted_horizon(1.0, 1) == 1.0
    for gamma, horizon in ((-0.1, 5), (0.5, 0)):
        with pytest.raises(
            ValueError,
            match=rf"^need gamma in \[0, 1\] and horizon >= 1, got {gamma} and {horizon}$",
        ):
            discounted_horizon(gamma, horizon)
    heads = reward_keys("r+rf+rsp")
    small = {keys.PENALTY_SURPRISE: 0.5}  # a span below 1 is a span
    lows, highs = head_supports(
        heads, v_min=-1.0, v_max=1.0, bounded=False, dense_span=0.25, spans=small
    )
    assert lows == [-1.0, -0.25, -0.5] and highs == [1.0, 0.25, 0.5]
    with pytest.raises(
        ValueError,
        match=r"^spans must map reward keys of \[.*\] to > 0, got \{'penalty_surprise': 0.0\}$",
    ):
        head_supports(
            heads, v_min=-1.0, v_max=1.0, bounded=False, spans={keys.PENALTY_SURPRISE: 0.0}
        )
    with pytest.raises(ValueError, match=r"^dense_span must be > 0 \(or None\), got -1.0$"):
        head_supports(heads, v_min=-1.0, v_max=1.0, bounded=False, dense_span=-1.0)


def test_a_bound_at_the_heads_bottom_is_not_applied():
    """A penalty head (never above 0) whose support starts at 0: capping it there would leave
    [0, 0], so it keeps [0, v_max]."""
    heads = [keys.PENALTY]
    assert head_supports(heads, v_min=0.0, v_max=5.0, bounded=True) == ([0.0], [5.0])
    assert head_supports(heads, v_min=-0.5, v_max=5.0, bounded=True) == ([-0.5], [0.0])


def test_critic_supports_span_the_dense_heads_bounds_times_the_horizon():
    from gentlerl.config import NetworkConfig

    heads = reward_keys("r+rf+rsp+rF")  # task, penalty, penalty surprise, force penalty
    network = NetworkConfig(
        v_min=-4.0, v_max=6.0, bounded_support=True, dense_reward_bound=0.5,
        penalty_surprise_bound=3.0,
    )  # fmt: skip
    lows, highs = critic_supports(heads, network, horizon=10.0)
    assert lows == [-4.0, -5.0, -30.0, -5.0]
    assert highs == [6.0, 0.0, 30.0, 0.0]
    shared = NetworkConfig(
        v_min=-4.0, v_max=6.0, bounded_support=False, dense_reward_bound=None,
        penalty_surprise_bound=None,
    )  # fmt: skip
    assert critic_supports(heads, shared, horizon=10.0) == ([-4.0] * 4, [6.0] * 4)
    only_rsp = NetworkConfig(
        v_min=-4.0, v_max=6.0, bounded_support=True, dense_reward_bound=None,
        penalty_surprise_bound=2.0,
    )  # fmt: skip
    assert critic_supports(heads, only_rsp, horizon=10.0) == (
        [-4.0, -4.0, -20.0, -4.0], [6.0, 0.0, 20.0, 0.0],
    )  # fmt: skip


def test_a_derived_support_covers_every_discounted_return_with_headroom():
    from gentlerl.config import EnvConfig, NetworkConfig
    from gentlerl.rewards.variants import derived_support, derives_support, task_reward_bounds

    # dm_control: r in [0, 1], 1000 steps at gamma 0.99 -> H = 99.996; [0, H] +- 10 % of H.
    horizon = discounted_horizon(0.99, 1000)
    low, high = derived_support((0.0, 1.0), horizon)
    assert (low, high) == pytest.approx((-0.1 * horizon, 1.1 * horizon))
    assert derived_support((-2.0, -1.0), 10.0, headroom=0.0) == (-20.0, 0.0)  # 0: a cut episode
    with pytest.raises(ValueError, match="leave every return at 0"):
        derived_support((0.0, 0.0), 10.0)
    external = EnvConfig(name="dm_control:finger-spin")
    assert task_reward_bounds(external) == (0.0, 1.0)
    assert derives_support(external, NetworkConfig()) and not derives_support(
        EnvConfig(), NetworkConfig()
    )
    assert task_reward_bounds(EnvConfig(reward_bounds=(-1.0, 5.0))) == (-1.0, 5.0)
    v_min, v_max = critic_supports(
        [keys.REWARD, keys.EXCESS_PENALTY], NetworkConfig(), horizon, (low, high)
    )
    assert v_min == pytest.approx([low, -horizon]) and v_max == pytest.approx([high, 0.0])
