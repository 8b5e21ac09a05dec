"""The penalty transforms refuse bad lambdas and name a missing ``next`` entry or force key."""

from __future__ import annotations

import pytest
import torch


@pytest.mark.parametrize(
    ("cls", "lam"),
    [
        ("ImpactPenalty", (float("nan"), 2.0)),
        ("ImpactPenalty", (2.0, -5.0)),
        ("ImpactPenalty", (2.0,)),
        ("ImpactPenalty", (-1.0, 2.0)),
        ("ImpactPenalty", "ab"),
        ("ForcePenalty", (float("nan"), 8.0)),
        ("ForcePenalty", (2.0, float("inf"))),
        ("TorquePenalty", (1.0, 2.0, 3.0)),
    ],
)
def test_bad_lambdas_are_refused(cls, lam):
    import gentlerl.transforms as transforms

    with pytest.raises(ValueError, match=f"{cls} lam must be two finite numbers"):
        getattr(transforms, cls)(lam=lam)


def test_transforms_name_a_missing_next_or_key():
    from tensordict import TensorDict

    from gentlerl.transforms import ForcePenalty, ImpactPenalty

    with pytest.raises(ValueError, match="needs a transition: a tensordict with a 'next' entry"):
        ImpactPenalty()(TensorDict({"touch": torch.zeros(5, 3)}))
    td = TensorDict({"force": torch.zeros(5, 3), "next": {"force": torch.zeros(5, 3)}})
    for transform in (ImpactPenalty(), ForcePenalty()):
        with pytest.raises(ValueError, match="reads 'touch', which the tensordict lacks"):
            transform(td.clone())
    td = TensorDict({"touch": torch.zeros(5, 3), "next": {"touch": torch.zeros(4, 3)}})
    with pytest.raises(ValueError, match=r"must be \[..., n_sites, n_channels\] at both steps"):
        ImpactPenalty()(td)


def _normalized_rsp():
    """An r^sp transform with the normalised curiosity (Method III), on the toy hand."""
    from gentlerl.config import GentlenessConfig
    from gentlerl.rewards import IntrinsicRewards
    from tests.toy_env import ToyHandEnv

    settings = GentlenessConfig(curiosity_norm=True, model_hidden=16, reward_delay=0)
    rewards = IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", settings)
    return rewards, rewards.transform[1]


@pytest.mark.parametrize(
    "value",
    [
        (float("nan"), 3), (float("inf"), 3), (-1.0, 3), (True, 3), ("2.0", 3),
        (2.0, -1), (2.0, 2.5), (2.0, True), (2.0, float("nan")), (2.0,), (2.0, 3, 4),
    ],
)  # fmt: skip
def test_a_tampered_curiosity_scale_is_refused_naming_it_and_leaves_the_scale(value):
    _, rsp = _normalized_rsp()
    rsp.curiosity_scale = (2.0, 3)
    with pytest.raises(ValueError, match=r"PenaltySurprise curiosity_scale=.* must be \(mean"):
        rsp.curiosity_scale = value
    assert rsp.curiosity_scale == (2.0, 3)


def test_a_checkpoint_with_a_non_finite_curiosity_scale_is_refused_naming_it():
    rewards, rsp = _normalized_rsp()
    state = rewards.state_dict()
    state["curiosity_scales"] = [[float("nan"), 3]]
    with pytest.raises(ValueError, match=r"PenaltySurprise curiosity_scale=\(nan, 3\)"):
        rewards.load_state_dict(state)
    assert rsp.curiosity_scale == (0.0, 0)
