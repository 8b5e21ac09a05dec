"""``RewardChain``: the entries a variant's transforms read, named when a batch lacks them, and
the device its models live on."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.chain import RewardChain
from gentlerl.transforms import ImpactPenalty

SMALL = dict(model_hidden=8, ensemble_size=2)


def _chain(variant: str) -> RewardChain:
    return IntrinsicRewards(
        variant, GentlenessConfig(**SMALL), obs_dim=3, action_dim=2, feature_shapes={},
        obs_key="state", force_key="force",
    ).transform  # fmt: skip


def _transition(**drop) -> TensorDict:
    """A 4-step batch with every entry a model reward reads, less those named in ``drop``."""
    td = TensorDict(
        {
            "state": torch.zeros(4, 3),
            keys.ACTION: torch.zeros(4, 2),
            "force": torch.zeros(4, 2, 3),
            "next": {"state": torch.ones(4, 3), "force": torch.ones(4, 2, 3)},
        },
        [4],
    )
    for key in drop:
        del td[tuple(key.split("__"))]
    return td


def _missing(chain: RewardChain, td: TensorDict) -> str:
    with pytest.raises(KeyError) as refused:
        chain(td)
    return refused.value.args[0]


def test_a_model_reward_chain_names_each_missing_entry_and_where():
    chain = _chain("r+rf+rsp")
    message = _missing(chain, _transition(state=1, next__force=1))
    assert message == (
        "IntrinsicRewards reads 'state' (obs_key), ('next', 'force') (force_key), which the "
        "tensordict lacks; it has ['action', 'force', 'next'] (pass obs_key= / force_key= to "
        "name the env's entries)"
    )
    message = _missing(chain, _transition(action=1, next__state=1, force=1))
    assert message.startswith(
        "IntrinsicRewards reads ('next', 'state') (obs_key), 'action' (action), 'force' "
        "(force_key), which the tensordict lacks; it has ['next', 'state'] "
    )
    chain(_transition())  # all there: it scores


def test_a_chain_without_a_model_reads_the_force_only():
    chain = _chain("r+rf")
    chain(_transition(state=1, next__state=1, action=1))  # the impact penalty needs no more
    message = _missing(chain, _transition(force=1))
    assert message.startswith(
        "IntrinsicRewards reads 'force' (force_key), which the tensordict lacks; it has "
        "['action', 'next', 'state'] "
    )


def test_the_chain_names_its_models_device_and_scores_a_batch_where_it_is():
    chain = RewardChain(ImpactPenalty(in_keys=["force"]), obs_key="state", force_key="force")
    assert chain.models_device is None and (chain.obs_key, chain.force_key) == ("state", "force")
    on_cpu = RewardChain(
        ImpactPenalty(in_keys=["force"]), obs_key="state", force_key="force", device="cpu"
    )
    assert on_cpu.models_device == torch.device("cpu")
    for td in (_transition(), _transition().to("cpu")):
        out = on_cpu(td)
        assert out is td and out.device == td.device
        assert out["next", keys.PENALTY].shape == (4, 1)


def test_one_transition_is_scored_and_an_empty_batch_refused_in_full():
    chain = _chain("r+rf")
    out = chain(_transition()[:1])
    assert out["next", keys.PENALTY].shape == (1, 1)
    with pytest.raises(ValueError) as refused:
        chain(_transition()[:0])
    assert str(refused.value) == "the reward transforms got an empty batch (0,)"


def test_a_chain_without_a_models_device_scores_a_batch_where_it_is():
    chain = RewardChain(ImpactPenalty(in_keys=["force"]), obs_key="state", force_key="force")
    for td in (_transition(), _transition().to("cpu")):
        out = chain(td)
        assert out is td and out.device == td.device
