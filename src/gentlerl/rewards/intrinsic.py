"""``IntrinsicRewards``: a variant's reward transforms, the models behind them and how they learn.

The models learn from 1-step transitions (s_t, a_t, s_{t+1}, r^f_t) in their own uniform buffer;
every model update is followed by the paper's schedule: hard target copies every
``target_period`` updates, and the curiosity rewards switched on after ``reward_delay`` updates.
Both periods count :meth:`IntrinsicRewards.update` calls (one gradient step of each model).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import torch
from tensordict import TensorDictBase
from torchrl.data import ReplayBuffer
from torchrl.objectives import HardUpdate

from gentlerl import keys
from gentlerl.config import GentlenessConfig, check_group
from gentlerl.data import make_model_buffer
from gentlerl.deprecation import moved_method
from gentlerl.functional import tolerance_unit
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.rewards.chain import RewardChain
from gentlerl.rewards.env_sizes import env_sizes
from gentlerl.rewards.lagrangian import CostLagrangian
from gentlerl.rewards.model_step import ModelStep
from gentlerl.rewards.multiplier import ImpactMultiplier
from gentlerl.rewards.rescore import Rescoring
from gentlerl.rewards.variants import COMPONENTS, Ingredients, reward_keys
from gentlerl.transforms import ImpactPenalty, ModelRewardTransform, PenaltySurprise

if TYPE_CHECKING:
    from torchrl.envs import EnvBase


class IntrinsicRewards(Rescoring):
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
    ``transform.check_keys`` says which of them a tensordict lacks. :meth:`from_env` reads every
    size from an env's specs; ``device`` is where the models and their buffer live; ``compile``
    and ``cudagraphs`` launch each model's step as the learner's is (:class:`ModelStep`).

    With ``settings.rescore_surprise`` (the default), penalty surprise must be scored again
    when sampled: an n-step buffer (gentlerl's loop) calls :meth:`rescore_windows`; a 1-step one
    appends :meth:`rescore_transform`. :meth:`update` raises once the rewards are
    on if neither ever ran, rather than training on stale curiosity without a word.
    """

    #: Deprecated (removed in 0.3.0): :meth:`rescore_transform`.
    sampling_transform = moved_method("sampling_transform", "rescore_transform")

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
        device: torch.device | str | None = None,
        compile: bool = False,
        cudagraphs: bool = False,
    ) -> None:
        check_group(settings, "gentleness")  # what `gentlerl train` checks of the same fields
        self.reward_keys = reward_keys(variant)
        self.settings = settings
        self.obs_key, self.force_key = obs_key, force_key
        self.device = torch.device("cpu" if device is None else device)
        self._launch = {"compile": compile, "cudagraphs": cudagraphs}  # each model's step
        if self.device.type not in ("cpu", "cuda"):
            raise ValueError(f"IntrinsicRewards: device must be cpu or cuda, got {self.device}")
        #: Model updates so far (:meth:`update` counts them; the schedule reads it).
        self.num_updates = 0
        self._rescorers, self._rescored_windows, self._updates_while_on = [], False, 0
        ing = Ingredients(obs_dim, action_dim, feature_shapes, settings, seed, obs_key, force_key)
        with self.device:
            self._build(ing)

    def _build(self, ing: Ingredients) -> None:
        """The transforms, losses, target updaters, optimisers and buffer of the variant."""
        settings, force_key = ing.settings, ing.force_key
        # impact is logged for every variant; the force key is any [..., n_sites, n_channels] entry
        unit = (
            1.0
            if settings.tolerance is None
            else tolerance_unit(settings.tolerance, settings.lam[1])
        )
        transforms: list = [ImpactPenalty(settings.lam, unit=unit, in_keys=[force_key])]
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
        self.transform = RewardChain(
            *transforms, obs_key=ing.obs_key, force_key=force_key, device=self.device
        )
        #: Each model's step (built on first use, unless :meth:`share_steps` gave the group's),
        #: and this seed's row in it.
        self._steps: dict[str, ModelStep] | None = None
        self._seat = 0
        #: The penalty's weight steered toward ``settings.tolerance`` (``multiplier=pid``).
        self.multiplier = (
            ImpactMultiplier(
                settings.tolerance,
                settings.multiplier_gains,
                period=settings.multiplier_period,
                integral_max=settings.multiplier_integral_max,
                base=settings.multiplier_base,
            )
            if settings.multiplier == "pid"
            else None
        )
        #: The episodes' cost held under ``settings.cost_limit`` (``multiplier=lagrangian``).
        self.lagrangian = (
            CostLagrangian(
                settings.cost_limit,
                settings.cost_gains,
                warmup_frames=settings.cost_warmup_frames,
                multiplier_max=settings.cost_multiplier_max,
                period=settings.cost_period,
            )
            if settings.multiplier == "lagrangian"
            else None
        )
        self.buffer: ReplayBuffer | None = (
            make_model_buffer(settings.model_buffer_size, device=self.device)
            if self.losses
            else None
        )

    @classmethod
    def from_env(
        cls,
        env: EnvBase,
        variant: str,
        settings: GentlenessConfig | None = None,
        *,
        force_key: str = keys.TOUCH,
        obs_key: str = keys.OBSERVATION,
        seed: int = 0,
        device: torch.device | str | None = None,
    ) -> IntrinsicRewards:
        """The rewards of ``variant`` for ``env``, every size read from its specs.

        ``obs_key`` (``[..., obs_dim]``) and ``force_key`` (``[..., n_sites, n_channels]``) name
        the env's entries; the dynamics model (variants with ``rs``) predicts the hand's feature
        groups where the env has them, else the entries its ``observation`` concatenates, else
        the observation itself. ``settings`` defaults to :class:`~gentlerl.config.GentlenessConfig`.
        """
        obs_dim, action_dim, feature_shapes = env_sizes(env, obs_key, force_key)
        return cls(
            variant,
            settings if settings is not None else GentlenessConfig(),
            obs_dim=obs_dim,
            action_dim=action_dim,
            feature_shapes=feature_shapes,
            seed=seed,
            force_key=force_key,
            obs_key=obs_key,
            device=device,
        )

    def head_weights(self) -> dict[str, float]:
        """The actor's weights on the heads the multiplier steers now: the penalty's
        ``1 + mu`` (``multiplier=pid``), every head's ``1 / (1 + lambda)`` or
        ``lambda / (1 + lambda)`` (``multiplier=lagrangian``), none without a multiplier."""
        if self.multiplier is not None:
            return {keys.PENALTY: self.multiplier.weight}
        if self.lagrangian is not None:
            return dict(
                zip(self.reward_keys, self.lagrangian.weights(self.reward_keys), strict=True)
            )
        return {}

    @property
    def gated_transforms(self) -> list[ModelRewardTransform]:
        return [t for t in self.transform if isinstance(t, ModelRewardTransform)]

    @property
    def _normalized(self) -> list[PenaltySurprise]:
        """The penalty surprises whose curiosity is normalised (``settings.curiosity_norm``)."""
        return [t for t in self.gated_transforms if getattr(t, "normalize", False)]

    @property
    def intrinsic_on(self) -> bool:
        gated = self.gated_transforms
        return bool(gated) and bool(gated[0].active)

    def extend(self, batch: TensorDictBase) -> None:
        """Keep a collected (transformed) batch's 1-step transitions for the models."""
        if batch.batch_size.numel() == 0:
            raise ValueError(f"IntrinsicRewards.extend: the batch is empty {tuple(batch.shape)}")
        if self.buffer is not None:
            touch_grid = (keys.TOUCH_GRID, ("next", keys.TOUCH_GRID))
            self.buffer.extend(batch.exclude(*touch_grid, "collector").reshape(-1))

    def model_batches(self) -> dict[str, TensorDictBase]:
        """Each model's training batch for one update, from the models' buffer: ``[E, B]`` for
        an ensemble (a bootstrap batch per member), ``[B]`` otherwise (``B``:
        ``model_batch_size``). :meth:`update` steps each model on its batch; a group of seeds
        (:meth:`share_steps`) stacks the seeds' batches into one step."""
        if self.buffer is not None and len(self.buffer) == 0:
            raise RuntimeError(
                "IntrinsicRewards.update() before any extend(): the models have no transition to "
                "learn from (extend() each collected, transformed batch first)"
            )
        self._check_rescored()
        b, batches = self.settings.model_batch_size, {}
        for name, loss in self.losses.items():
            if isinstance(loss, EnsembleModelLoss):
                e = loss.ensemble_size
                batches[name] = self.buffer.sample(e * b).reshape(e, b)
            else:
                batches[name] = self.buffer.sample(b)
        return batches

    def update(self, num_updates: int | None = None) -> dict[str, float]:
        """One gradient step of every model, then :meth:`step`; returns ``model_<name>`` losses.

        ``num_updates``: the count including this update (default: one more than the last);
        ``reward_delay`` and the target periods are counted in these updates.
        """
        if any(step.num_seeds != 1 for step in self.steps.values()):
            raise RuntimeError(
                "IntrinsicRewards.update: these models step with other seeds' (share_steps); "
                "the group's update steps them"
            )
        batches = self.model_batches()
        metrics = {
            f"model_{name}": self.steps[name](batch.unsqueeze(0)).item()
            for name, batch in batches.items()
        }
        self.step(num_updates)
        return metrics

    @property
    def steps(self) -> dict[str, ModelStep]:
        """Each model's :class:`~gentlerl.rewards.model_step.ModelStep`: this seed's own, built
        on first use, or the group's after :meth:`share_steps` (then no own one is built)."""
        if self._steps is None:
            self._steps = {
                name: ModelStep(loss, self.settings.lr_model, **self._launch)
                for name, loss in self.losses.items()
            }
        return dict(self._steps)

    def share_steps(self, steps: Mapping[str, ModelStep], seat: int) -> None:
        """Train this seed's models as row ``seat`` of ``steps`` (one per model, over several
        seeds' losses, this one's among them), whose caller steps them; the state this seed
        saves and loads is its row's."""
        if set(steps) != set(self.losses):
            raise ValueError(
                f"share_steps: steps for {sorted(steps)}, models {sorted(self.losses)}"
            )
        for name, step in steps.items():
            if step.losses[seat] is not self.losses[name]:
                raise ValueError(f"share_steps: row {seat} of the {name!r} step is not this model")
        self._steps, self._seat = dict(steps), seat

    def step(self, num_updates: int | None = None) -> None:
        """Call once after each model update, with the total update count (paper's schedule;
        default: one more than the last).

        Copies each model into its target every ``target_period`` calls (TorchRL ``HardUpdate``)
        and switches the intrinsic rewards on once ``num_updates >= reward_delay``.
        """
        num_updates = self.num_updates + 1 if num_updates is None else int(num_updates)
        self.num_updates = num_updates
        for updater in self._updaters.values():
            updater.step()
        on = num_updates >= self.settings.reward_delay
        for t in self.gated_transforms:
            t.active.fill_(on)

    def state_dict(self) -> dict[str, Any]:
        """Models, optimisers and schedule (the buffer is saved with the other buffers)."""
        return {
            "losses": {name: loss.state_dict() for name, loss in self.losses.items()},
            "optimizers": {n: st.optimizer_state(self._seat) for n, st in self.steps.items()},
            "active": self.intrinsic_on,
            "target_counters": {name: u.counter for name, u in self._updaters.items()},
            "num_updates": self.num_updates,
            "curiosity_scales": [list(t.curiosity_scale) for t in self._normalized],
            "multiplier": self.multiplier.state_dict() if self.multiplier else None,
            "lagrangian": self.lagrangian.state_dict() if self.lagrangian else None,
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        for name, loss in self.losses.items():
            loss.load_state_dict(state["losses"][name])
            self.steps[name].load_optimizer_state(state["optimizers"][name], self._seat)
        for t in self.gated_transforms:
            t.active.fill_(bool(state["active"]))
        for name, counter in state["target_counters"].items():
            self._updaters[name].counter = counter
        self.num_updates = int(state.get("num_updates", 0))  # absent before the count was kept
        for t, (mean, count) in zip(  # [] in checkpoints before curiosity_norm
            self._normalized, state.get("curiosity_scales", []), strict=False
        ):
            t.curiosity_scale = (mean, count)  # the setter checks them
        if self.multiplier is not None and state.get("multiplier") is not None:
            self.multiplier.load_state_dict(state["multiplier"])
        if self.lagrangian is not None and state.get("lagrangian") is not None:
            self.lagrangian.load_state_dict(state["lagrangian"])
