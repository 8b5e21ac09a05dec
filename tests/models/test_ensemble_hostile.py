"""PenaltyModel names a missing or wrongly sized observation."""

from __future__ import annotations

import pytest
import torch


def test_a_penalty_model_names_a_missing_or_wrongly_sized_observation():
    from tensordict import TensorDict

    from gentlerl.models import PenaltyModel

    model = PenaltyModel(4, 2, 3, (8, 8, 8))
    with pytest.raises(ValueError, match=r"'observation' of size 4, got shape \(5, 7\)"):
        model.predict(
            TensorDict({"observation": torch.zeros(5, 7), "action": torch.zeros(5, 2)}, [5])
        )
    with pytest.raises(KeyError, match="'action'"):
        model.predict(TensorDict({"observation": torch.zeros(5, 4)}, [5]))
