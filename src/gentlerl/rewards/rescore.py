"""``RescoreRewards``: the model-reading rewards recomputed on each sampled batch (a replay-buffer
transform), so that curiosity is scored by the model of the update, not of the collection.

Stored at collection, a surprise reward keeps the verdict of the model of that moment: a bonus for
a contact the model has learned since never fades. Appended to a TorchRL ``ReplayBuffer``
(``rb.append_transform(...)``), this transform scores every sampled 1-step transition again with
the current (target) models and, given a :class:`~gentlerl.rewards.SumRewards`, sums the
components again. n-step transitions need each step's window (gentlerl's own loop keeps them, see
:meth:`gentlerl.rewards.IntrinsicRewards.rescore_windows`) and are refused here.
"""

from __future__ import annotations

from collections.abc import Sequence

from tensordict import TensorDictBase
from torchrl.envs.transforms import Transform

from gentlerl.rewards.sum import SumRewards
from gentlerl.transforms.base import ModelRewardTransform


class RescoreRewards(Transform):
    """Recomputes ``rewards`` (model-reading transforms, gate included) on each sampled batch.

    The transforms are shared, not copied: they keep reading the models (and the reward-delay
    gate) that the losses train. ``reads`` counts the batches scored.

    Args:
        rewards: the model-reading transforms, e.g. ``IntrinsicRewards.gated_transforms``.
        reward_sum: applied after them, to sum the fresh components again (optional).
    """

    def __init__(
        self, rewards: Sequence[ModelRewardTransform], reward_sum: SumRewards | None = None
    ) -> None:
        super().__init__()
        # Plain attributes: the transforms belong to the env's chain, which checkpoints them.
        self.__dict__["rewards"] = tuple(rewards)
        self.__dict__["reward_sum"] = reward_sum
        self.reads = 0

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        steps = tensordict.get("steps_to_next_obs", None)
        if steps is not None and bool((steps > 1).any()):
            raise ValueError(
                "RescoreRewards scores 1-step transitions; this batch holds n-step ones "
                f"(steps_to_next_obs up to {int(steps.max())}), whose rewards are sums over "
                "steps it does not have: sample 1-step transitions, or use gentlerl's loop"
            )
        for transform in self.rewards:
            transform(tensordict)
        if self.reward_sum is not None:
            self.reward_sum(tensordict)
        self.reads += 1
        return tensordict
