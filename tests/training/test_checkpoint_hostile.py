"""A policy file cannot demand an allocation and its sizes must match its weights; a full disk keeps
the previous checkpoint."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch

from tests.helpers import policy_file


def test_a_policy_demanding_a_huge_actor_is_refused_before_allocating(tmp_path):
    from gentlerl.training.checkpoint import CheckpointError, load_policy

    path = policy_file(tmp_path, [200000, 200000], [16])
    with pytest.raises(CheckpointError, match=r"actor_hidden=\[200000, 200000\]: each value must"):
        load_policy(path)


def test_a_policy_whose_config_and_weights_disagree_is_one_line(tmp_path):
    from gentlerl.training.checkpoint import CheckpointError, load_policy

    with pytest.raises(CheckpointError) as err:
        load_policy(policy_file(tmp_path, [32], [16]))
    assert "\n" not in str(err.value) and "policy.pt" in str(err.value)
    assert len(load_policy(policy_file(tmp_path, [16], [16]))) == 2


def test_disk_full_says_so_and_keeps_the_previous_checkpoint(tmp_path, monkeypatch):
    from gentlerl.training import checkpoint

    path = tmp_path / "checkpoint.pt"
    checkpoint.save_checkpoint(path, {"frames": torch.tensor(1)})

    def full(*args, **kwargs):
        raise RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos 64 vs 0")

    monkeypatch.setattr(checkpoint.torch, "save", full)
    monkeypatch.setattr(
        checkpoint.shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(1, 1, 0)
    )
    with pytest.raises(OSError, match="no space left on device writing .* is intact"):
        checkpoint.save_checkpoint(path, {"frames": torch.tensor(2)})
    monkeypatch.undo()
    assert int(checkpoint.load_checkpoint(path)["frames"]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint.pt"]


def _saved_policy(tmp_path: Path, obs_dim: int, actor: dict) -> Path:
    from gentlerl.training.checkpoint import save_checkpoint
    from gentlerl.training.config import preset_config

    path = tmp_path / "policy.pt"
    config = preset_config().to_dict()
    save_checkpoint(path, {"config": config, "obs_dim": obs_dim, "action_dim": 20, "actor": actor})
    return path


def test_a_policy_of_expanded_or_oversized_weights_is_refused_before_allocating(tmp_path):
    from gentlerl.models import make_actor
    from gentlerl.training.checkpoint import CheckpointError, load_policy

    obs_dim = 50_000_000  # 256 x 50M floats: 51 GB if the actor were built
    with torch.device("meta"):
        shapes = {k: v.shape for k, v in make_actor(obs_dim, 20, (256, 256)).state_dict().items()}
    expanded = {k: torch.zeros(1).expand(*shape) for k, shape in shapes.items()}
    path = _saved_policy(tmp_path, obs_dim, expanded)
    assert path.stat().st_size < 100_000  # what the file holds: one float per tensor
    with pytest.raises(CheckpointError, match=r"is not a dense tensor \(shape \[256, 50000000\]"):
        load_policy(path)
    dense = make_actor(10, 20, (256, 256)).state_dict()  # the shapes are compared after the size
    with pytest.raises(CheckpointError, match=r"would have 12,800,\d{3},\d{3} parameters, more"):
        load_policy(_saved_policy(tmp_path, obs_dim, dense))


def test_an_interrupt_inside_torch_save_surfaces_as_itself(tmp_path, monkeypatch):
    """Ctrl-C / SIGTERM striking inside ``torch.save``: its zip writer's exit then fails with a
    RuntimeError; the save raises the interrupt, and the old checkpoint is left as it was."""
    import torch

    from gentlerl.apps.errors import Terminated
    from gentlerl.training import checkpoint

    path = tmp_path / "checkpoint.pt"
    checkpoint.save_checkpoint(path, {"frames": 1})

    def struck(obj, f):
        try:
            raise Terminated(15)
        finally:  # what torch's _open_zipfile_writer.__exit__ does on the way out
            raise RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos 64 vs 0")

    monkeypatch.setattr(torch, "save", struck)
    with pytest.raises(Terminated):
        checkpoint.save_checkpoint(path, {"frames": 2})
    monkeypatch.undo()
    assert checkpoint.load_checkpoint(path)["frames"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint.pt"]
