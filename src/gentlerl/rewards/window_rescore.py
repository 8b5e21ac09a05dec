"""``WindowRescorer``: the sampled n-step windows of S seeds (S = 1 for one run) re-scored for
r^sp, on a GPU as one vmapped forward of their target penalty ensembles.

The loop samples one batch per seed and stacks them ``[S, B]``. Each seed's penalty surprise
(eq. 8) must be scored again with that seed's own target penalty model
(:meth:`~gentlerl.rewards.IntrinsicRewards.rescore_windows` does it for one seed). Vmapped, the
S target models' parameters are stacked on a seed axis (each seed's own target tensors then
share its row, so the target updater's in-place copies land in the stack) and one ``torch.vmap``
of :meth:`~gentlerl.transforms.PenaltySurprise.curiosity` scores every window step of every
seed: one model's kernels, S times wider, and one host read per update (the seeds'
per-contact-step means, read together; with ``curiosity_norm`` also each seed's running scale),
instead of S forwards each behind a data-dependent selection.

The vmapped forward reads every row and keeps eq. 8's value on the rows it is defined on
(:meth:`~gentlerl.transforms.PenaltySurprise.scored_rows`), 0 elsewhere: the same numbers as the
one-seed path (tested to 1e-5), which reads the model on contact rows only. On a CPU that subset
is the cheaper one (3 seeds, recipe ensemble, 128 x 5-step windows, one thread: 5.4 ms per
update in a loop over seeds at 30 % contact, 11 ms at 100 %, against 17-19 ms vmapped), so there
the seeds are scored one by one (``vmapped=None``: vmapped on a CUDA device only).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

from gentlerl.data import contact_step_sum, nstep_return, window_of
from gentlerl.models.stacking import seed_stack, shared_stack
from gentlerl.transforms import PenaltySurprise

if TYPE_CHECKING:
    from gentlerl.rewards.intrinsic import IntrinsicRewards


class WindowRescorer:
    """``rescorer(batches, gamma)``: S seeds' sampled n-step transitions stacked ``[S, B]`` with
    their r^sp recomputed from their windows, each seed with its own target penalty model; the
    same as S calls of ``rewards[s].rescore_windows(batches[s], gamma)``.

    Args:
        rewards: one :class:`~gentlerl.rewards.IntrinsicRewards` per seed, of one variant and
            equal settings, checked (their
            :attr:`~gentlerl.rewards.IntrinsicRewards.rescored` transforms are re-scored).
            Vmapped, the seeds' target parameters are made views of the stack's rows.
        vmapped: one vmapped forward for every seed (True) or each seed's own
            ``rescore_windows`` (False); ``None``: vmapped where the models are on a CUDA device.
    """

    def __init__(self, rewards: Sequence[IntrinsicRewards], vmapped: bool | None = None) -> None:
        if len(rewards) < 1:
            raise ValueError("WindowRescorer needs at least one seed's rewards, got 0")
        first = (rewards[0].reward_keys, rewards[0].settings)
        differ = [s for s, r in enumerate(rewards) if (r.reward_keys, r.settings) != first]
        if differ:
            raise ValueError(
                f"WindowRescorer: the rewards of seeds {differ} differ from seed 0's in their "
                "variant or gentleness settings; a group's seeds share both"
            )
        per_seed = [list(r.rescored) for r in rewards]
        self.rewards, self.num_seeds = list(rewards), len(rewards)
        self.vmapped = rewards[0].device.type == "cuda" if vmapped is None else vmapped
        #: ``[kind][seed]``: each rescored reward of every seed (vmapped only).
        self.transforms: list[list[PenaltySurprise]] = (
            [list(ts) for ts in zip(*per_seed, strict=True)] if self.vmapped else []
        )
        self.params = [shared_stack([t.params for t in seeds]) for seeds in self.transforms]
        self._curiosity = [
            torch.vmap(partial(_curiosity, seeds[0]), (0, 0, 0)) for seeds in self.transforms
        ]

    def __call__(
        self, batches: Sequence[TensorDictBase], gamma: float
    ) -> tuple[TensorDictBase, list[dict[str, float]]]:
        """The seeds' sampled batches (one ``[B]`` each) stacked ``[S, B]``, with ``("next",
        <r^sp key>)`` re-scored; and each seed's ``<key>_per_contact_step`` (absent where its
        batch has no contact)."""
        if len(batches) != self.num_seeds:
            raise ValueError(
                f"WindowRescorer needs one batch per seed ({self.num_seeds}), got {len(batches)}"
            )
        if not self.vmapped:  # each seed on its contact rows only, then stacked
            metrics = [
                r.rescore_windows(b, gamma) for r, b in zip(self.rewards, batches, strict=True)
            ]
            return seed_stack(batches), metrics
        batch = seed_stack(batches)
        return batch, self._vmapped(batch, gamma)

    def _vmapped(self, batch: TensorDictBase, gamma: float) -> list[dict[str, float]]:
        """Every seed's r^sp of ``batch`` ``[S, B]`` replaced in place, one forward per kind."""
        metrics: list[dict[str, float]] = [{} for _ in self.rewards]
        if not self.transforms:
            return metrics
        window, steps = window_of(batch), batch.get("steps_to_next_obs")
        flat = window.reshape(self.num_seeds, -1).to(self.rewards[0].device)
        for seeds, params, curiosity in zip(
            self.transforms, self.params, self._curiosity, strict=True
        ):
            key = seeds[0].out_keys[0]
            per_step = self._scored(seeds, params, curiosity, flat)
            per_step = per_step.reshape(*window.batch_size, 1).to(steps.device)
            batch.set(("next", key), nstep_return(per_step, steps, gamma))
            total, count = contact_step_sum(
                per_step, window.get(("next", seeds[0].penalty_key)), steps
            )
            for seed_metrics, t, c in zip(metrics, total.tolist(), count.tolist(), strict=True):
                if c > 0:
                    seed_metrics[f"{key}_per_contact_step"] = t / c
        for r in self.rewards:
            r.mark_windows_rescored()
        return metrics

    def _scored(
        self,
        seeds: list[PenaltySurprise],
        params: TensorDictBase,
        curiosity: Callable[..., torch.Tensor],
        flat: TensorDictBase,
    ) -> torch.Tensor:
        """``[S, R, 1]``: eq. 8 of every seed's ``R`` window steps, gated per seed."""
        template = seeds[0]
        keys = (template.model.obs_key, template.model.action_key)
        model_in = flat.select(*keys)
        penalty = flat.get(("next", template.penalty_key))
        rows = template.scored_rows(model_in.reshape(-1), penalty.reshape(-1))
        rows = rows.reshape(penalty.shape[:-1]).unsqueeze(-1)
        values = curiosity(params, model_in, penalty)
        if template.normalize:  # each seed's running scale, folded from its own contact rows
            for s, t in enumerate(seeds):
                values[s][rows[s]] = t.normalized(values[s][rows[s]], learn=True)
        values = torch.where(rows, template.surprise(penalty, values), 0.0)
        gates = torch.stack([t.gate(values.dtype) for t in seeds])
        return values * gates.reshape(-1, 1, 1)


def _curiosity(
    template: PenaltySurprise, params: TensorDictBase, model_in: TensorDictBase, hit: torch.Tensor
) -> torch.Tensor:
    """One seed's curiosity (eq. 8's surprise) on every row, under its target ``params``."""
    return template.curiosity(model_in, hit, params)
