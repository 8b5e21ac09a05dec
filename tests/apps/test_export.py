"""Shipped policies: a run's final actor as a small file that ``load_policy`` and
``gentlerl evaluate`` read, laid out as ``<task>/<variant>/seed<k>.pt``."""

import csv

import pytest
import torch
from tensordict import TensorDict

from gentlerl.apps.evaluate import evaluate_policy
from gentlerl.apps.export import export_runs, main, policy_path
from gentlerl.models import make_actor
from gentlerl.training import Trainer, load_checkpoint, load_policy, make_config, save_checkpoint
from gentlerl.training.checkpoint import POLICY_KEYS, CheckpointError, export_policy
from tests.helpers import tiny_config, toy_env


def test_exported_policy_acts_and_evaluates_like_the_checkpoint(tmp_path):
    run = Trainer(tiny_config(tmp_path / "run", total_frames=300), toy_env)
    run.run()
    ckpt = tmp_path / "run" / "checkpoint.pt"
    policy = export_policy(ckpt, tmp_path / "touch" / "r+rf+rsp" / "seed0.pt")
    state = load_checkpoint(policy)
    assert sorted(state) == sorted([*POLICY_KEYS, "frames"]) and state["frames"] == 300
    assert policy.stat().st_size < ckpt.stat().st_size / 5  # no buffer, critics or models
    assert not list(policy.parent.glob(".*.tmp"))
    cfg, actor = load_policy(policy)
    assert cfg == run.cfg
    obs = TensorDict({"observation": torch.randn(5, 63)}, [5])
    assert torch.equal(actor(obs.clone())["action"], run.learner.actor(obs.clone())["action"])
    # On the hand: the same deterministic episodes as the checkpoint, rows for gentlerl plot.
    csv_path = tmp_path / "final_eval_episodes.csv"
    shipped = evaluate_policy(policy, 2, seed=0, episodes_csv=csv_path)
    assert shipped == evaluate_policy(ckpt, 2, seed=0)
    rows = list(csv.DictReader(csv_path.open()))
    assert [r["frames"] for r in rows] == ["300", "300"] and len(rows) == shipped["episodes"]
    assert sum(int(r["success"]) for r in rows) / 2 == shipped["success_rate"]


def _checkpoint(path, task="touch", variant="r", seed=0, lam2=2.0, hidden=(8,), env_name=None):
    cfg = make_config(
        task=task, variant=variant, seed=seed, gentleness={"lam_prime": (2.0, lam2)},
        network={"actor_hidden": hidden},
    ).to_dict()  # fmt: skip
    cfg["env"]["name"] = env_name  # a run on an external env keeps task's default ("touch")
    actor = make_actor(63, 20, hidden)
    state = {"config": cfg, "obs_dim": 63, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(path, {**state, "counters": {"frames": 60_000}, "rb": torch.zeros(1000, 100)})
    return path


def test_runs_export_to_task_variant_seed_at_the_primary_lambda(tmp_path, capsys):
    runs = tmp_path / "runs"
    _checkpoint(runs / "a" / "checkpoint.pt", "touch", "r", seed=3)
    _checkpoint(runs / "b" / "checkpoint.pt", "touch", "r+rf+rsp", lam2=2.0)  # touch's primary
    _checkpoint(runs / "c" / "checkpoint.pt", "touch", "r+rf+rsp", lam2=3.0)
    _checkpoint(runs / "d" / "checkpoint.pt", "fragile", "r+rf+rsp", seed=1, lam2=1.5)
    _checkpoint(runs / "e" / "checkpoint.pt", "explore", "rs")  # not a touch / fragile run
    _checkpoint(
        runs / "f" / "checkpoint.pt", "touch", "r", seed=5, env_name="dm_control:finger-spin"
    )
    main([str(runs), "--out", str(tmp_path / "policies")])
    written = sorted(p.relative_to(tmp_path / "policies").as_posix()
                     for p in (tmp_path / "policies").rglob("*.pt"))  # fmt: skip
    assert written == ["fragile/r+rf+rsp/seed1.pt", "touch/r+rf+rsp/seed0.pt", "touch/r/seed3.pt"]
    assert "3 policies under" in capsys.readouterr().out
    out = export_runs([runs], tmp_path / "all", all_lambdas=True)
    assert tmp_path / "all/touch/r+rf+rsp@lam3/seed0.pt" in out and len(out) == 4
    assert load_checkpoint(tmp_path / "all/touch/r/seed3.pt")["frames"] == 60_000


def test_a_default_size_actor_ships_well_under_a_megabyte(tmp_path):
    ckpt = _checkpoint(tmp_path / "checkpoint.pt", hidden=(256, 256))  # the CPU-scale actor
    size = export_policy(ckpt, tmp_path / "policy.pt").stat().st_size
    assert 300_000 < size < 400_000  # 87.6k float32 weights + config


def test_export_errors_name_the_files(tmp_path):
    _checkpoint(tmp_path / "x" / "checkpoint.pt", seed=0)
    _checkpoint(tmp_path / "y" / "checkpoint.pt", seed=0)
    with pytest.raises(ValueError, match="would both be exported to .*touch/r/seed0.pt"):
        export_runs([tmp_path], tmp_path / "out")
    save_checkpoint(tmp_path / "bad.pt", {"counters": {"frames": 1}})
    with pytest.raises(CheckpointError, match="bad.pt is not a gentlerl policy file"):
        export_policy(tmp_path / "bad.pt", tmp_path / "p.pt")
    with pytest.raises(FileNotFoundError, match="no such file or run directory"):
        export_runs([tmp_path / "nope"], tmp_path / "out")
    config = {
        "task": "touch",
        "variant": "r+rf+rsp",
        "seed": 2,
        "gentleness": {"lam_prime": [2, 1]},
    }
    assert policy_path(config, tmp_path) is None


def test_a_checkpoint_with_the_flat_config_of_older_versions_exports_grouped(tmp_path):
    flat = dict(task="fragile", variant="r+rf+rsp", seed=4, lam_prime=[2.0, 1.5], actor_hidden=[8])
    actor = make_actor(63, 20, (8,))
    state = {"config": flat, "obs_dim": 63, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(tmp_path / "run" / "checkpoint.pt", state)
    (policy,) = export_runs([tmp_path / "run"], tmp_path / "out")
    assert policy == tmp_path / "out" / "fragile" / "r+rf+rsp" / "seed4.pt"  # primary 1.5
    shipped = load_checkpoint(policy)
    assert shipped["config"]["gentleness"]["lam_prime"] == (2.0, 1.5)
    assert shipped["frames"] is None  # an older best_policy.pt does not say
