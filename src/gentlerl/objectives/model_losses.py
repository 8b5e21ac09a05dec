"""Losses of the models behind the intrinsic rewards: dynamics / penalty ensembles and ICM.

Each is a TorchRL ``LossModule`` so the training loop treats it like any loss, and each owns the
network that its reward transform reads (the pattern of TorchRL's RND loss / transform pair).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.objectives import HardUpdate
from torchrl.objectives.common import LossModule

from gentlerl.models.ensemble import DynamicsModel, PenaltyModel
from gentlerl.models.icm import ICMModel


class ModelHardUpdate(HardUpdate):
    """TorchRL's ``HardUpdate`` of an :class:`EnsembleModelLoss`'s target, normaliser statistics
    included.

    TorchRL's target updaters copy only the entries that take a gradient (the weights). A model's
    running normaliser statistics (:class:`~gentlerl.models.RunningNorm` buffers: the inputs',
    and the dynamics model's per-feature deltas') would stay at their initial values in the
    target (mean 0, var 1), which would then read trained weights on un-normalised inputs and
    score every surprise (eqs. 6 and 8) on wrongly scaled inputs. Each copy here also copies
    them, in place (views of the target, e.g. a seed group's stacked rows, stay valid).

    Args:
        loss_module: the model's loss (its ``model_params`` and ``target_model_params``).
        value_network_update_interval: as TorchRL's: the copy comes on every
            ``(interval + 1)``-th :meth:`step` call; an integer >= 0 (TorchRL's ``HardUpdate``
            takes any number and, with ``-1``, ``1.5`` or ``"5"``, never copies).
    """

    def __init__(
        self, loss_module: LossModule, *, value_network_update_interval: int = 1000
    ) -> None:
        interval = value_network_update_interval
        if isinstance(interval, bool) or not isinstance(interval, int) or interval < 0:
            raise ValueError(
                f"value_network_update_interval must be an integer >= 0 (the target is copied "
                f"every interval + 1 steps), got {interval!r}"
            )
        super().__init__(loss_module, value_network_update_interval=interval)

    def step(self) -> None:
        copies = self.counter == self.value_network_update_interval
        super().step()
        if copies:
            with torch.no_grad():
                self.loss_module.target_model_params.update_(self.loss_module.model_params)


class EnsembleModelLoss(LossModule):
    """Gaussian NLL of a :class:`DynamicsModel` or :class:`PenaltyModel` ensemble.

    Bootstrap (paper: "trained on different batches of transitions"): with ``per_member=True``
    member e is trained on its own transitions. Pass either ``[E, B]`` (member e gets ``batch[e]``,
    e.g. ``rb.sample(E * B).reshape(E, B)``) or a flat ``[B]`` batch, which :meth:`bootstrap`
    resamples with replacement once per member. With ``False`` a ``[B]`` batch is shared by all
    members (they still differ by their seeded initialisation).

    The loss keeps a *target* copy of the model (``target_model_params``, normaliser statistics
    included) for the surprise transforms; update it with :class:`ModelHardUpdate` (paper: every
    5000 dynamics / 1000 penalty model updates), not TorchRL's plain ``HardUpdate``, which
    leaves the statistics behind. Each ``forward`` in training mode first merges the batch into
    the model's running input / target statistics.

    Returns ``loss_<name>``: the NLL averaged over members and samples.
    """

    model: DynamicsModel | PenaltyModel
    model_params: TensorDictBase
    target_model_params: TensorDictBase

    def __init__(
        self, model: DynamicsModel | PenaltyModel, *, name: str, per_member: bool = True
    ) -> None:
        super().__init__()
        if not name.isidentifier():
            raise ValueError(f"name must be an identifier (it becomes loss_<name>), got {name!r}")
        self.name = name
        self.per_member = per_member
        self.convert_to_functional(model, "model", create_target_params=True)

    @property
    def ensemble_size(self) -> int:
        return self.model.ensemble_size

    def bootstrap(self, tensordict: TensorDictBase) -> TensorDictBase:
        """``[E, B]`` as given; a flat ``[B]`` batch as ``[E, B]``, one bootstrap resample per member.

        Each member draws ``B`` transitions with replacement (torch's global RNG) from the batch.
        """
        size, e = tensordict.batch_size, self.ensemble_size
        if len(size) == 2 and size[0] == e:
            return tensordict
        if len(size) == 1 and size[0] > 0:
            index = torch.randint(size[0], (e, size[0]), device=tensordict.device)
            return tensordict[index]
        raise ValueError(
            f"per_member=True needs a flat batch [B] or one shaped [ensemble_size={e}, B], "
            f"got {tuple(size)}"
        )

    def losses(self, tensordict: TensorDictBase, params: TensorDictBase) -> TensorDict:
        """``loss_<name>`` of the model whose parameters and normaliser statistics are ``params``
        (the structure of ``model_params``); in training mode the statistics in ``params`` first
        take in the batch. ``torch.vmap`` over a stack of ``params`` runs several seeds' models
        at once (:class:`~gentlerl.rewards.model_step.ModelStep`)."""
        if self.per_member:
            tensordict = self.bootstrap(tensordict)
        with params.to_module(self.model, preserve_module_state=False):
            if self.training:
                self.model.update_normalizers(tensordict)
            nll = self.model.nll(tensordict, per_member=self.per_member)
        return TensorDict({f"loss_{self.name}": nll.mean()}, batch_size=[])

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        return self.losses(tensordict, self.model_params)

    def predict_target(self, tensordict: TensorDictBase) -> object:
        """The *target* model's ``predict`` (no gradient), as the surprise transforms use it."""
        with (
            torch.no_grad(),
            self.target_model_params.to_module(self.model, preserve_module_state=False),
        ):
            return self.model.predict(tensordict)


class ICMLoss(LossModule):
    r"""ICM loss :math:`(1 - \beta) L_{inverse} + \beta L_{forward}` (Pathak et al. 2017, eq. 7), beta = 0.2.

    :math:`L_{inverse}` is the MSE between predicted and taken actions (continuous actions),
    :math:`L_{forward} = \frac12 \lVert \hat\phi(s_{t+1}) - \phi(s_{t+1}) \rVert^2` with the
    encoder trained by the inverse loss only (``phi(s_{t+1})`` is detached in the forward loss, a
    common guard against feature collapse).
    """

    model: ICMModel
    model_params: TensorDictBase
    target_model_params: TensorDictBase

    def __init__(self, model: ICMModel, *, beta: float = 0.2) -> None:
        super().__init__()
        if not 0.0 <= beta <= 1.0:
            raise ValueError(f"beta must be in [0, 1], got {beta}")
        self.beta = beta
        self.convert_to_functional(model, "model", create_target_params=False)

    def predict(
        self, tensordict: TensorDictBase, params: TensorDictBase | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The model's predictions with ``params`` (the structure of ``model_params``; its own
        by default)."""
        params = self.model_params if params is None else params
        with params.to_module(self.model, preserve_module_state=False):
            return self.model.predict(tensordict)

    def losses(self, tensordict: TensorDictBase, params: TensorDictBase) -> TensorDict:
        """``loss_icm`` (and its two terms, detached) of the model whose parameters are
        ``params``; a pure function of its inputs, so ``torch.vmap`` over a stack of ``params``
        steps several seeds' models at once (:class:`~gentlerl.rewards.model_step.ModelStep`)."""
        predicted_action, predicted_next, next_phi = self.predict(tensordict, params)
        inverse = nn.functional.mse_loss(predicted_action, tensordict.get(self.model.action_key))
        forward = 0.5 * (predicted_next - next_phi.detach()).pow(2).sum(-1).mean()
        return TensorDict(
            {
                "loss_icm": (1 - self.beta) * inverse + self.beta * forward,
                "icm_inverse": inverse.detach(),
                "icm_forward": forward.detach(),
            },
            batch_size=[],
        )

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        return self.losses(tensordict, self.model_params)
