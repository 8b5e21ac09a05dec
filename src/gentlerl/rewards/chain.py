"""``RewardChain``: a variant's reward transforms, which first check that a batch holds their keys."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.envs.transforms import Compose

from gentlerl import keys
from gentlerl.transforms import ModelRewardTransform


class RewardChain(Compose):
    """The reward transforms; applied to a batch, first checks that it holds what they read.

    ``device``: where the reward models are (``None``: wherever the batch is). A batch applied
    from elsewhere (a CPU collector's, a GPU learner's models) is scored there and returned on
    its own device.
    """

    def __init__(
        self,
        *transforms,
        obs_key: str,
        force_key: str,
        device: torch.device | str | None = None,
    ) -> None:
        super().__init__(*transforms)
        self.obs_key, self.force_key = obs_key, force_key
        self.models_device = None if device is None else torch.device(device)

    def check_keys(self, tensordict: TensorDictBase) -> None:
        """A ``KeyError`` naming the entries that ``tensordict`` lacks: the force (at the root and
        under ``"next"``) and, for learned rewards, the observation (both) and the action."""
        wanted = {self.force_key: "force_key"}
        if any(isinstance(t, ModelRewardTransform) for t in self):  # the models read s_t, a_t
            wanted = {self.obs_key: "obs_key", keys.ACTION: "action", **wanted}
        present = set(tensordict.keys(True))
        missing = [
            f"{where!r} ({name})"
            for key, name in wanted.items()
            for where in ((key,) if key == keys.ACTION else (key, ("next", key)))
            if where not in present
        ]
        if missing:
            raise KeyError(
                f"IntrinsicRewards reads {', '.join(missing)}, which the tensordict lacks; it has "
                f"{sorted(map(str, tensordict.keys()))} (pass obs_key= / force_key= to name the "
                "env's entries)"
            )

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self.check_keys(tensordict)
        if tensordict.batch_size.numel() == 0:
            raise ValueError(f"the reward transforms got an empty batch {tuple(tensordict.shape)}")
        home, there = tensordict.device, self.models_device
        if there is None or home is None or home == there:
            return super().forward(tensordict)
        return super().forward(tensordict.to(there)).to(home)
