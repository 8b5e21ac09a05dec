"""``ICMReward``: the curiosity reward of Pathak et al. 2017 (the paper's ICM baseline)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

from gentlerl import keys
from gentlerl.transforms.base import ModelRewardTransform

if TYPE_CHECKING:  # the models are passed in; transforms import no model code
    from gentlerl.models.icm import ICMModel


class ICMReward(ModelRewardTransform):
    r"""Writes ``icm_reward`` :math:`\frac{\eta}{2}\lVert \hat\phi(s_{t+1}) - \phi(s_{t+1}) \rVert^2` ``[1]``.

    Reads ``model`` with ``params``: the online parameters of its
    :class:`~gentlerl.objectives.ICMLoss` (``model_params``); 0 until :attr:`active`.
    ``eta`` must be >= 0.
    """

    def __init__(
        self,
        model: ICMModel,
        params: TensorDictBase,
        *,
        eta: float = 1.0,
        out_key: str = keys.ICM_REWARD,
    ) -> None:
        # eta / 2 is the reward's scale.
        super().__init__(model, params, out_key, 0.5 * eta, [model.obs_key, model.action_key])

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        td = tensordict.select(*self.in_keys).set("next", next_tensordict.select(self.in_keys[0]))
        _, predicted_next, next_phi = self.predict(td)
        error = (predicted_next - next_phi).pow(2).sum(-1, keepdim=True)
        return {self.out_keys[0]: self._gate(error)}
