"""``IntrinsicRewards``: a variant's reward transforms, the models behind them and how they learn.

The models learn from 1-step transitions (s_t, a_t, s_{t+1}, r^f_t) in their own uniform buffer;
every model update is followed by the paper's schedule: hard target copies every
``target_period`` updates, and the curiosity rewards switched on after ``reward_delay`` updates.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torchrl.data import ReplayBuffer
from torchrl.envs.transforms import Compose
from torchrl.objectives import HardUpdate

from gentlerl import keys
from gentlerl.agent.variants import COMPONENTS, Ingredients, reward_keys
from gentlerl.data import WINDOW, make_model_buffer, nstep_return
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.transforms import ImpactPenalty, ModelRewardTransform, PenaltySurprise

if TYPE_CHECKING:
    from gentlerl.config import GentlenessConfig


class IntrinsicRewards:
    """The reward transforms of a variant, their models' losses, optimisers, schedule and buffer.

    Attributes:
        transform: writes ``impact``, ``penalty`` and the variant's other rewards under
            ``"next"``; apply it to collected batches (``transform(batch)``) or append it to an env.
        reward_keys: the reward components, in critic-head order.
        losses: model name -> its loss (``{}`` without learned rewards).
        buffer: the models' 1-step transitions (``None`` without learned rewards).

    Works on any env with an observation entry ``obs_key`` (``[..., obs_dim]``, default
    ``observation``), ``action`` and a force entry ``force_key`` shaped
    ``[..., n_sites, n_channels]`` (the hand's ``touch``, ``[5, 3]``); ``feature_shapes`` names the
    entries the dynamics model predicts (used by the variants with dynamics surprise only).
    ``transform.check_keys`` says which of them a tensordict lacks.
    """

    def __init__(
        self,
        variant: str,
        settings: GentlenessConfig,
        *,
        obs_dim: int,
        action_dim: int,
        feature_shapes: Mapping[str, Sequence[int]],
        seed: int = 0,
        force_key: str = keys.TOUCH,
        obs_key: str = keys.OBSERVATION,
    ) -> None:
        self.reward_keys = reward_keys(variant)
        self.settings = settings
        self.obs_key, self.force_key = obs_key, force_key
        ing = Ingredients(obs_dim, action_dim, feature_shapes, settings, seed, obs_key, force_key)
        # impact is logged for every variant; the force key is any [..., n_sites, n_channels] entry
        transforms: list = [ImpactPenalty(settings.lam, in_keys=[force_key])]
        self.losses: dict[str, Any] = {}
        self._updaters: dict[str, HardUpdate] = {}
        for key in self.reward_keys:
            component = COMPONENTS[key]
            if component.build is None:
                continue
            part = component.build(ing)
            transforms.append(part.transform)
            if part.loss is not None:
                self.losses[component.model] = part.loss
            if part.target_updater is not None:
                self._updaters[component.model] = part.target_updater
        self.transform = _Rewards(*transforms, obs_key=obs_key, force_key=force_key)
        self.optimizers = {
            # fused: one kernel per step instead of ~10 per parameter tensor
            name: torch.optim.Adam(loss.parameters(), lr=settings.lr_model, fused=True)
            for name, loss in self.losses.items()
        }
        self.buffer: ReplayBuffer | None = (
            make_model_buffer(settings.model_buffer_size) if self.losses else None
        )

    @property
    def gated_transforms(self) -> list[ModelRewardTransform]:
        return [t for t in self.transform if isinstance(t, ModelRewardTransform)]

    @property
    def recomputed(self) -> list[PenaltySurprise]:
        """The rewards recomputed at sampling (``settings.recompute_surprise``): penalty surprise."""
        if not self.settings.recompute_surprise:
            return []
        return [t for t in self.gated_transforms if isinstance(t, PenaltySurprise)]

    @property
    def window_keys(self) -> list[NestedKey]:
        """What the learner's buffer keeps of each window step for :meth:`refresh`."""
        wanted: list[NestedKey] = []
        for t in self.recomputed:
            wanted += [t.model.obs_key, t.model.action_key, ("next", t.penalty_key)]
        return list(dict.fromkeys(wanted))

    def refresh(self, batch: TensorDictBase, gamma: float) -> dict[str, float]:
        r"""Recompute the n-step penalty surprise of a sampled batch with today's target models.

        Stored at collection, :math:`r^{s_p}` (eq. 8) would keep the surprise of the model of that
        moment: a bonus for a contact the model has learned since never fades. Here each
        transition's window of raw steps (``"window"``, written by the ``NStepWriter`` with
        :attr:`window_keys`) is scored again and summed as ``MultiStepTransform`` summed it
        (:func:`~gentlerl.data.nstep_return`); ``("next", "penalty_surprise")`` is replaced in
        place. Returns ``penalty_surprise_per_contact_step``: the mean recomputed :math:`r^{s_p}`
        over the window steps with a penalty (absent when the batch has none), the number that
        falls when the model learns what it is paid to be surprised by.
        """
        metrics: dict[str, float] = {}
        if not self.recomputed:
            return metrics
        window = batch.get(WINDOW, None)
        if window is None:
            raise KeyError(
                "recompute_surprise needs each transition's window of steps ('window'), written "
                "by an NStepWriter given window_keys=IntrinsicRewards.window_keys"
            )
        flat, steps = window.reshape(-1), batch.get("steps_to_next_obs")
        for t in self.recomputed:
            key = t.out_keys[0]
            per_step = t.compute(flat, flat.get("next"))[key].reshape(*window.batch_size, 1)
            batch.set(("next", key), nstep_return(per_step, steps, gamma))
            contact = window.get(("next", t.penalty_key)) < 0
            counted = torch.arange(window.shape[-1], device=steps.device) < steps.reshape(-1, 1)
            counted = contact & counted.unsqueeze(-1)
            if counted.any():  # a batch without contact says nothing about the bonus's size
                metrics[f"{key}_per_contact_step"] = per_step[counted].mean().item()
        return metrics

    @property
    def intrinsic_on(self) -> bool:
        gated = self.gated_transforms
        return bool(gated) and bool(gated[0].active)

    def extend(self, batch: TensorDictBase) -> None:
        """Keep a collected (transformed) batch's 1-step transitions for the models."""
        if self.buffer is not None:
            touch_grid = (keys.TOUCH_GRID, ("next", keys.TOUCH_GRID))
            self.buffer.extend(batch.exclude(*touch_grid, "collector").reshape(-1))

    def update(self, num_updates: int) -> dict[str, float]:
        """One gradient step of every model, then :meth:`step`; returns ``model_<name>`` losses."""
        metrics = {}
        b = self.settings.model_batch_size
        for name, loss in self.losses.items():
            if isinstance(loss, EnsembleModelLoss):
                e = loss.ensemble_size
                batch = self.buffer.sample(e * b).reshape(e, b)  # a bootstrap batch per member
            else:
                batch = self.buffer.sample(b)
            out = loss(batch)
            total = sum(v for k, v in out.items() if k.startswith("loss_"))
            self.optimizers[name].zero_grad()
            total.backward()
            self.optimizers[name].step()
            metrics[f"model_{name}"] = total.item()
        self.step(num_updates)
        return metrics

    def step(self, num_updates: int) -> None:
        """Call once after each model update, with the total update count (paper's schedule).

        Copies each model into its target every ``target_period`` calls (TorchRL ``HardUpdate``)
        and switches the intrinsic rewards on once ``num_updates >= reward_delay``.
        """
        for updater in self._updaters.values():
            updater.step()
        on = num_updates >= self.settings.reward_delay
        for t in self.gated_transforms:
            t.active.fill_(on)

    def state_dict(self) -> dict[str, Any]:
        """Models, optimisers and schedule (the buffer is saved with the other buffers)."""
        return {
            "losses": {name: loss.state_dict() for name, loss in self.losses.items()},
            "optimizers": {name: o.state_dict() for name, o in self.optimizers.items()},
            "active": self.intrinsic_on,
            "target_counters": {name: u.counter for name, u in self._updaters.items()},
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        for name, loss in self.losses.items():
            loss.load_state_dict(state["losses"][name])
            self.optimizers[name].load_state_dict(state["optimizers"][name])
        for t in self.gated_transforms:
            t.active.fill_(bool(state["active"]))
        for name, counter in state["target_counters"].items():
            self._updaters[name].counter = counter


class _Rewards(Compose):
    """The reward transforms; applied to a batch, first checks that it holds what they read."""

    def __init__(self, *transforms, obs_key: str, force_key: str) -> None:
        super().__init__(*transforms)
        self.obs_key, self.force_key = obs_key, force_key

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
        return super().forward(tensordict)
