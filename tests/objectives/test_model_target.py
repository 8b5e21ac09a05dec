"""The reward models' target copies: weights *and* normaliser statistics (ModelHardUpdate).

TorchRL's HardUpdate copies only the entries that take a gradient; a target left with its
initial normaliser statistics reads trained weights on un-normalised inputs."""

import pytest
import torch
from tensordict import TensorDict
from torchrl.objectives import HardUpdate

from gentlerl.config import GentlenessConfig
from gentlerl.models import PenaltyModel
from gentlerl.objectives import EnsembleModelLoss, ModelHardUpdate
from gentlerl.rewards import IntrinsicRewards


def _transitions(n=64):
    g = torch.Generator().manual_seed(0)
    flags = torch.zeros(n, 1, dtype=torch.bool)
    return TensorDict(
        {
            "observation": torch.randn(n, 3, generator=g) * 3 + 2,
            "action": torch.rand(n, 2, generator=g),
            "next": {
                "observation": torch.randn(n, 3, generator=g) * 2 + 1,
                "penalty": -5 * torch.rand(n, 1, generator=g),
                "reward": torch.zeros(n, 1),
                "done": flags, "terminated": flags.clone(), "truncated": flags.clone(),
            },
        },
        [n],
    )  # fmt: skip


def _normaliser_entries(params):
    return {k: v for k, v in params.items(True, True) if "norm" in "".join(map(str, k))}


@pytest.mark.parametrize("variant", ["r+rf+rsp", "r+rf+rs"])
def test_every_target_copy_takes_the_normaliser_statistics_too(variant):
    settings = GentlenessConfig(
        reward_delay=0, model_hidden=16, ensemble_size=3, rescore_surprise=False,
        penalty_target_period=2, dynamics_target_period=2,
    )  # fmt: skip
    rewards = IntrinsicRewards(
        variant, settings, obs_dim=3, action_dim=2, feature_shapes={"observation": (3,)}
    )
    rewards.extend(_transitions())
    (loss,) = rewards.losses.values()
    rewards.update()  # the statistics move; no copy yet
    online, target = (
        _normaliser_entries(loss.model_params),
        _normaliser_entries(loss.target_model_params),
    )
    assert online and all(not torch.equal(online[k], target[k]) for k in online)
    rewards.update()  # the second update copies
    for key, value in loss.model_params.items(True, True):
        torch.testing.assert_close(loss.target_model_params.get(key), value, rtol=0, atol=0)


def test_torchrls_own_hard_update_leaves_the_statistics_behind():
    """Why ModelHardUpdate exists: the same copy through TorchRL's updater."""
    losses = [EnsembleModelLoss(PenaltyModel(3, 2, ensemble_size=2, hidden=(8,)), name="p")
              for _ in range(2)]  # fmt: skip
    updaters = [HardUpdate(losses[0], value_network_update_interval=0),
                ModelHardUpdate(losses[1], value_network_update_interval=0)]  # fmt: skip
    batch = _transitions().select("observation", "action", ("next", "penalty"))
    for loss, updater in zip(losses, updaters, strict=True):
        loss(batch)  # training mode: the input statistics take in the batch
        updater.step()
    plain, ours = (_normaliser_entries(loss.target_model_params) for loss in losses)
    assert plain["input_norm", "count"].item() < 1e-3  # still the initial statistics
    torch.testing.assert_close(ours, _normaliser_entries(losses[1].model_params))
