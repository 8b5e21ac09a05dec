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
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torchrl.envs.transforms import Transform

from gentlerl.data import rescore_windows
from gentlerl.rewards.sum import SumRewards
from gentlerl.transforms import ModelRewardTransform, PenaltySurprise

if TYPE_CHECKING:
    from gentlerl.config import GentlenessConfig


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


class Rescoring:
    """The one verb "rescore" of :class:`~gentlerl.rewards.IntrinsicRewards`: the curiosity scored
    again at sampling by a 1-step buffer's :meth:`rescore_transform` or an n-step buffer's
    :meth:`rescore_windows`, and the guard that refuses to train on stale curiosity when neither
    ever ran. The owner sets ``_rescorers``, ``_rescored_windows``, ``_updates_while_on`` and has
    ``settings``, ``device``, ``gated_transforms`` and ``intrinsic_on``.
    """

    settings: GentlenessConfig
    device: torch.device
    gated_transforms: list[ModelRewardTransform]
    intrinsic_on: bool
    _rescorers: list[RescoreRewards]
    _rescored_windows: bool
    _updates_while_on: int  # by this object: a resumed run starts again at 0

    def rescore_transform(self, reward_sum: SumRewards | None = None) -> RescoreRewards:
        """A replay-buffer transform that scores each sampled batch's curiosity (r^s, r^sp, ICM)
        again with the current models, then sums the components with ``reward_sum``.

        ``rb.append_transform(rewards.rescore_transform(reward_sum))`` on a buffer of 1-step
        transitions; an n-step buffer uses :meth:`rescore_windows` instead. Unlike that one
        (penalty surprise only, and only with ``rescore_surprise``), this transform scores every
        model-reading reward again, whatever ``rescore_surprise`` says: a 1-step transition
        holds all it needs, so nothing is left stale.
        """
        rescorer = RescoreRewards(self.gated_transforms, reward_sum)
        self._rescorers.append(rescorer)
        return rescorer

    def _check_rescored(self) -> None:
        """Refuse a second update with the rewards on if r^sp is to be rescored at sampling
        and never was (the first may come before its batch is sampled)."""
        if not self.rescored or not self.intrinsic_on:
            return
        self._updates_while_on += 1
        if self._updates_while_on < 2 or self._rescored_windows:
            return
        if any(rescorer.reads for rescorer in self._rescorers):
            return
        raise RuntimeError(
            "rescore_surprise=True, but penalty surprise was never scored again at sampling: "
            "append rewards.rescore_transform() to the replay buffer (or call rescore_windows() on "
            "n-step batches), or set GentlenessConfig(rescore_surprise=False)"
        )

    def mark_windows_rescored(self) -> None:
        """Record that this object's :attr:`rescored` rewards were scored again at sampling by a
        scorer of several seeds' batches at once
        (:class:`~gentlerl.rewards.window_rescore.WindowRescorer`), as
        :meth:`rescore_windows` records it for one."""
        self._rescored_windows = True

    @property
    def rescored(self) -> list[PenaltySurprise]:
        """The rewards scored again at sampling (``settings.rescore_surprise``): penalty surprise."""
        if not self.settings.rescore_surprise:
            return []
        return [t for t in self.gated_transforms if isinstance(t, PenaltySurprise)]

    @property
    def window_keys(self) -> list[NestedKey]:
        """What the learner's buffer keeps of each window step for :meth:`rescore_windows`."""
        wanted: list[NestedKey] = []
        for t in self.rescored:
            wanted += [t.model.obs_key, t.model.action_key, ("next", t.penalty_key)]
        return list(dict.fromkeys(wanted))

    def rescore_windows(self, batch: TensorDictBase, gamma: float) -> dict[str, float]:
        r"""Recompute the n-step penalty surprise of a sampled batch with today's target models.

        Stored at collection, :math:`r^{s_p}` (eq. 8) would keep the surprise of the model of that
        moment: a bonus for a contact the model has learned since never fades. Here each
        transition's window of raw steps (``"window"``, written by the ``NStepWriter`` with
        :attr:`window_keys`) is scored again and summed as ``MultiStepTransform`` summed it
        (:func:`~gentlerl.data.rescore_windows`); ``("next", "penalty_surprise")`` is replaced in
        place. Returns ``penalty_surprise_per_contact_step``: the mean rescored :math:`r^{s_p}`
        over the window steps with a penalty (absent when the batch has none), the number that
        falls when the model learns what it is paid to be surprised by.
        """
        if not self.rescored:
            return {}
        self._rescored_windows = True
        return rescore_windows(self.rescored, batch, gamma, self.device)
