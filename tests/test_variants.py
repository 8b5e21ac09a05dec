"""The variants registry: reward components, head order, supports, curiosity heads."""

import pytest

from gentlerl import keys
from gentlerl.agent.variants import (
    COMPONENTS,
    VARIANTS,
    head_v_max,
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
    assert head_v_max(heads, 10.0, bounded=True) == [10.0, 0.0, 10.0]
    assert head_v_max(heads, 10.0, bounded=False) == [10.0, 10.0, 10.0]
    assert head_v_max(heads, -1.0, bounded=True) == [-1.0, -1.0, -1.0]  # never above v_max


def test_learned_components_name_their_model():
    built = {k: c.model for k, c in COMPONENTS.items() if c.build is not None}
    assert built == {
        keys.DYNAMICS_SURPRISE: "dynamics",
        keys.PENALTY_SURPRISE: "penalty",
        keys.ICM_REWARD: "icm",
        keys.FORCE_PENALTY: None,  # the wear penalties have a transform but no model
        keys.TORQUE_PENALTY: None,
    }
