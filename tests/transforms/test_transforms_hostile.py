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
