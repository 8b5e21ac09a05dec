"""Surprise rewards under a *target* ensemble: dynamics surprise (eq. 6), penalty surprise (eq. 8).

Each transform reads the target copy of the model owned by its
:class:`~gentlerl.objectives.EnsembleModelLoss` (the RND-style transform/loss pair): the loss trains
the model, the transform turns its predictions into a reward. Rewards are 0 until
:attr:`active` is switched on (the paper's 20,000-step reward delay; see
:class:`~gentlerl.rewards.IntrinsicRewards`).
"""

from __future__ import annotations

import contextlib
import numbers
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

from gentlerl import keys
from gentlerl.functional import (
    acceptability,
    gaussian_nll,
    gaussian_nll_parts,
    information_gain,
    mixture_moments,
    normalized_curiosity,
    penalty_surprise,
    running_mean_update,
)
from gentlerl.functional.constraint import is_finite_number
from gentlerl.transforms.base import ModelRewardTransform

#: What the curiosity part of r^sp reads (:class:`PenaltySurprise` ``kind``).
SURPRISE_KINDS = ("nll", "information_gain")

if TYPE_CHECKING:  # the models are passed in; transforms import no model code
    from torchrl.envs import Transform

    from gentlerl.models.ensemble import DynamicsModel, PenaltyModel


class DynamicsSurprise(ModelRewardTransform):
    r"""Writes ``dynamics_surprise`` :math:`r^s_t = -\sum_d \log \mathcal{N}(s_{t+1,d} \mid \mu_*, \sigma^2_*)` ``[1]``.

    :math:`\mu_*, \sigma^2_*` are the moments of the target ensembles' Gaussian mixture for
    :math:`(s_t, a_t)`, summed over every dimension of every feature group of the
    :class:`~gentlerl.models.DynamicsModel` (paper: joint positions, velocities and touch).

    Args:
        model: the dynamics ensemble.
        params: its parameters to read: the target copy of its loss (``target_model_params``).
        scale: multiplies the reward (1 = the paper's equation).
    """

    def __init__(
        self,
        model: DynamicsModel,
        params: TensorDictBase,
        *,
        scale: float = 1.0,
        out_key: str = keys.DYNAMICS_SURPRISE,
    ) -> None:
        in_keys = [model.obs_key, model.action_key, *model.feature_shapes]
        super().__init__(model, params, out_key, scale, in_keys)

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        predictions = self.predict(tensordict)
        total = 0.0
        for key, (mean, var) in predictions.items():
            mu, sigma2 = mixture_moments(mean, var, dim=0)
            target = next_tensordict.get(key).flatten(-len(self.model.feature_shapes[key]))
            total = total + gaussian_nll(target, mu, sigma2).sum(-1, keepdim=True)
        return {self.out_keys[0]: self._gate(total)}


class PenaltySurprise(ModelRewardTransform):
    r"""Writes ``penalty_surprise`` :math:`r^{s_p}_t` ``[1]`` (eq. 8) under the target penalty ensemble.

    .. math::
        r^{s_p}_t = a_{\lambda'}(|r^f_t|)\left[-\log \mathcal{N}(r^f_t \mid \mu_*, \sigma^2_*) - r^f_t\right]
        \text{ if } r^f_t < 0, \text{ else } 0.

    Reads ``("next", "penalty")``: put :class:`~gentlerl.transforms.ImpactPenalty` before it.
    The model is evaluated on the rows with a penalty only (the others are 0 by the equation).

    Args:
        model: the penalty ensemble.
        params: its parameters to read: the target copy of its loss (``target_model_params``).
        lam_prime: :math:`\lambda' = [\lambda'_1, \lambda'_2]` (paper: lambda'_1 = 2, lambda'_2 in 1..4).
        scale: multiplies the NLL only, :math:`a'(s \cdot \mathrm{nll} - r^f)`, so that
            :math:`r^f + r^{s_p} = a' s\,\mathrm{nll} + (1 - a') r^f` keeps eq. 7's refund of the
            penalty and shrinks (``s < 1``) or grows only the curiosity part (1 = the paper's
            equation). Scaling the whole reward would also shrink the refund and bring the
            penalty back rather than curiosity down.
        nll_floor: if set, the NLL is clamped from below at this value before eq. 8. The paper's
            equation (``None``) makes a *well*-predicted small penalty cost ``a' * nll < 0``, so
            once the penalty model is accurate, gentle contact is punished; a floor of 0 keeps the
            surprise a bonus ("erroneous predictions deliver a small positive reward").
        kind: what the curiosity part reads (:data:`SURPRISE_KINDS`): ``"nll"``, eq. 8's
            :math:`-\log \mathcal{N}(r^f_t \mid \mu_*, \sigma^2_*)`; ``"information_gain"``,
            the ensemble's disagreement :func:`~gentlerl.functional.information_gain` in its
            place (beyond the paper: the NLL of a wide or over-sure but unanimous model was
            measured not to fade as the model learns; the disagreement does). The refund
            :math:`-a' r^f` is kept either way; ``nll_floor`` applies to ``"nll"`` only.
        normalize: divide the curiosity by its running mean magnitude over the contact steps
            scored so far (:func:`~gentlerl.functional.running_mean_update`,
            :func:`~gentlerl.functional.normalized_curiosity`; Method III), so that it pays
            about 1 per contact step on every env; :attr:`curiosity_scale` holds
            ``(mean, count)`` (checkpointed by ``IntrinsicRewards``).
    """

    def __init__(
        self,
        model: PenaltyModel,
        params: TensorDictBase,
        *,
        lam_prime: tuple[float, float] = (2.0, 2.0),
        scale: float = 1.0,
        nll_floor: float | None = None,
        kind: str = "nll",
        normalize: bool = False,
        penalty_key: str = keys.PENALTY,
        out_key: str = keys.PENALTY_SURPRISE,
    ) -> None:
        if lam_prime[0] < 0:
            raise ValueError(f"lam_prime[0] (sigmoid steepness) must be >= 0, got {lam_prime}")
        if not scale >= 0:
            raise ValueError(f"scale must be >= 0, got {scale}")
        if kind not in SURPRISE_KINDS:
            raise ValueError(f"kind must be one of {SURPRISE_KINDS}, got {kind!r}")
        in_keys = [model.obs_key, model.action_key, penalty_key]
        super().__init__(model, params, out_key, 1.0, in_keys)
        self.nll_scale = float(scale)
        self.penalty_key = penalty_key
        self.lam_prime = (float(lam_prime[0]), float(lam_prime[1]))
        self.nll_floor = nll_floor
        self.kind = kind
        self.normalize = normalize
        #: Whether scoring folds a batch into :attr:`curiosity_scale` (off: :func:`frozen_scale`).
        self.learn_scale = True
        # [running mean magnitude of the curiosity on contact steps, batches it averages]: a
        # buffer changed in place, so that a clone (an env's copy) shares it as it shares the gate
        self.register_buffer("_scale", torch.zeros(2, dtype=torch.float64), persistent=False)

    @property
    def curiosity_scale(self) -> tuple[float, int]:
        """``(mean, count)``: the curiosity's running mean magnitude on contact steps and the
        batches it averages (checkpointed by ``IntrinsicRewards``)."""
        mean, count = self._scale.tolist()
        return mean, int(count)

    @curiosity_scale.setter
    def curiosity_scale(self, value: tuple[float, int]) -> None:
        """Set ``(mean, count)``: a finite mean >= 0 and an integer count >= 0 (a checkpoint's
        entry is checked here, so a tampered one cannot make every later r^sp non-finite)."""
        valid = (
            isinstance(value, tuple | list)
            and len(value) == 2
            and is_finite_number(value[0])
            and value[0] >= 0
            and isinstance(value[1], numbers.Integral)
            and not isinstance(value[1], bool)
            and value[1] >= 0
        )
        if not valid:
            shown = tuple(value) if isinstance(value, list) else value
            raise ValueError(
                f"PenaltySurprise curiosity_scale={shown!r} must be (mean, count): a finite mean >= 0 and an integer count >= 0"
            )
        self._scale.copy_(torch.tensor([float(value[0]), float(value[1])], dtype=torch.float64))

    def _curiosity(
        self, penalty: torch.Tensor, mean: torch.Tensor, var: torch.Tensor
    ) -> torch.Tensor:
        """The surprise inside eq. 8, before ``scale``: the (floored) NLL of ``penalty`` under
        the members' mixture, or their information gain (:attr:`kind`)."""
        if self.kind == "information_gain":
            return information_gain(mean, var, dim=0)
        mu, sigma2 = mixture_moments(mean, var, dim=0)
        nll = gaussian_nll(penalty, mu, sigma2)
        return nll if self.nll_floor is None else nll.clamp_min(self.nll_floor)

    def normalized(self, curiosity: torch.Tensor, learn: bool) -> torch.Tensor:
        """``curiosity`` in units of its running scale (with :attr:`normalize`); ``learn``: first
        fold this batch's mean magnitude (finite contact rows) into the scale."""
        if not self.normalize:
            return curiosity
        finite = curiosity[torch.isfinite(curiosity)]
        if learn and self.learn_scale and finite.numel():
            mean, count = self.curiosity_scale
            self.curiosity_scale = running_mean_update(mean, count, finite.abs().mean().item())
        return normalized_curiosity(curiosity, self.curiosity_scale[0])

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        penalty = next_tensordict.get(self.penalty_key)
        if penalty is None:
            raise KeyError(
                f"PenaltySurprise needs ('next', {self.penalty_key!r}): append ImpactPenalty first"
            )
        keys = (self.model.obs_key, self.model.action_key)
        for key in keys:
            self.read(tensordict, key)  # a missing input named in a clear error
        flat = penalty.reshape(-1)
        surprise = torch.zeros_like(flat)
        index = self.scored_rows(tensordict, flat).nonzero().squeeze(-1)
        if index.numel():  # the inputs gathered only where there is contact
            model_in = tensordict.select(*keys).reshape(-1)[index]
            hit = flat[index].unsqueeze(-1)
            curiosity = self.normalized(self.curiosity(model_in, hit), learn=True)
            surprise[index] = self.surprise(hit, curiosity).squeeze(-1)
        return {self.out_keys[0]: self._gate(surprise.reshape(penalty.shape))}

    def scored_rows(self, model_in: TensorDictBase, penalty: torch.Tensor) -> torch.Tensor:
        """``[N]`` which of ``N`` rows (``model_in``: ``N`` rows in any batch shape, ``penalty``
        ``[N]``) eq. 8 reads.

        Eq. 8 is 0 wherever r^f >= 0, so the model reads only the other rows: contacts (a
        minority of a training batch), and rows whose penalty or model input is not finite (so
        that NaN still reaches the reward). A diverged model shows on contact rows and in its
        own training loss, which the loop checks.
        """
        rows = ~(penalty >= 0)
        for key in (self.model.obs_key, self.model.action_key):
            rows |= ~torch.isfinite(model_in.get(key).reshape(penalty.shape[0], -1)).all(-1)
        return rows

    def curiosity(
        self, model_in: TensorDictBase, hit: torch.Tensor, params: TensorDictBase | None = None
    ) -> torch.Tensor:
        """The surprise inside eq. 8 of the penalties ``hit`` ``[N, 1]`` at ``model_in`` ``[N]``
        under :attr:`params` (or ``params``), before :attr:`normalize` and ``scale``."""
        return self._curiosity(hit, *self.predict(model_in, params))

    def surprise(self, hit: torch.Tensor, curiosity: torch.Tensor) -> torch.Tensor:
        """Eq. 8 on contact rows: :func:`~gentlerl.functional.penalty_surprise` of ``hit`` with
        the (normalised) ``curiosity`` times ``scale``, before the gate."""
        return penalty_surprise(hit, self.nll_scale * curiosity, *self.lam_prime)

    def sources(self, tensordict: TensorDictBase) -> dict[str, torch.Tensor]:
        r"""Where each step's :math:`r^{s_p}` comes from, under :attr:`params` (diagnostics).

        Per step, ``[..., 1]``: ``penalty`` :math:`r^f`, ``a_prime`` :math:`a'`, ``curiosity``
        :math:`a' s\,\mathrm{nll}` (the NLL floored as in :meth:`compute`, or the information
        gain, :attr:`kind`) and ``refund`` :math:`-a' r^f`, both gated as the reward is (0 before the switch), so that on a contact
        step :math:`r^{s_p}` = curiosity + refund; the (unfloored) NLL's ``spread`` and ``error``
        terms (:func:`~gentlerl.functional.gaussian_nll_parts`) and the mixture's variance (eq. 5)
        split into ``aleatoric`` (the members' mean variance) and ``epistemic`` (the variance of
        their means). Reads ``("next", penalty_key)``.
        """
        penalty = self.read(tensordict, ("next", self.penalty_key))
        mean, var = self.predict(tensordict)
        mu, sigma2 = mixture_moments(mean, var, dim=0)
        spread, error = gaussian_nll_parts(penalty, mu, sigma2)
        weight = acceptability(-penalty, *self.lam_prime)
        curiosity = self.normalized(self._curiosity(penalty, mean, var), learn=False)
        return {
            "penalty": penalty,
            "a_prime": weight,
            "curiosity": self._gate(weight * self.nll_scale * curiosity),
            "refund": self._gate(-weight * penalty),
            "spread": spread,
            "error": error,
            "aleatoric": var.mean(0),
            "epistemic": mean.var(0, unbiased=False),
        }


@contextlib.contextmanager
def frozen_scale(transforms: Iterable[Transform]) -> Iterator[None]:
    """Score with :class:`PenaltySurprise`'s running curiosity scale as it is, not learning
    from the batches (evaluations and diagnostics must not change what training reads)."""
    members = [t for t in transforms if isinstance(t, PenaltySurprise)]
    before = [t.learn_scale for t in members]
    for t in members:
        t.learn_scale = False
    try:
        yield
    finally:
        for t, learn in zip(members, before, strict=True):
            t.learn_scale = learn
