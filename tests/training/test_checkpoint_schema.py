"""Resuming a crafted or damaged checkpoint: every entry checked against the trainer before
anything is restored (issue 63), one line naming the file and the field; and a learning rate
changed on resume applied to the optimisers."""

import math
import subprocess
import sys

import pytest
import torch

from gentlerl.training import Trainer, load_checkpoint, save_checkpoint
from gentlerl.training.checkpoint_schema import CheckpointSchemaError
from tests.helpers import tiny_config, toy_env


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A tiny run's checkpoint (its reward models stepped, so their Adam state is saved)."""
    run_dir = tmp_path_factory.mktemp("run")
    Trainer(tiny_config(run_dir, total_frames=500), toy_env).run()
    return run_dir


def _state(saved):
    return load_checkpoint(saved / "checkpoint.pt")


def _moment(state, where="learner"):
    if where == "learner":
        return state["learner"]["optimizer"]["state"][0]
    (name,) = state["intrinsic"]["optimizers"]
    return state["intrinsic"]["optimizers"][name]["state"][0]


def _set(path, value):
    def tamper(state):
        *head, last = path
        for key in head:
            state = state[key]
        if value is KeyError:
            del state[last]
        else:
            state[last] = value(state[last]) if callable(value) else value

    return tamper


TAMPERS = [
    # Adam moments of another shape: the fused kernel aborted in native code
    (lambda s: _moment(s).update(exp_avg=torch.zeros(3, 3)), r"learner.optimizer state 0 .*"
     r"exp_avg has shape \[3, 3\], the parameter \[32, 63\]"),
    (lambda s: _moment(s).update(exp_avg_sq=_moment(s)["exp_avg_sq"][None]),
     r"exp_avg_sq has shape \[1, 32, 63\]"),  # an extra axis trained on silently
    (lambda s: _moment(s, "models").update(exp_avg=torch.zeros(2)),
     r"intrinsic.optimizers.penalty state 0 .*exp_avg has shape \[2\]"),  # segfaulted
    (lambda s: _moment(s).update(exp_avg=_moment(s)["exp_avg"].double()), "exp_avg is torch.float64"),
    (lambda s: _moment(s)["exp_avg"].fill_(math.nan), "exp_avg holds a NaN or infinite value"),
    (lambda s: _moment(s)["exp_avg_sq"].fill_(-1.0), "exp_avg_sq holds a negative value"),
    (lambda s: _moment(s).update(step=torch.tensor(math.inf)), "step tensor.inf. is not a finite"),
    (lambda s: _moment(s).pop("exp_avg"), r"lacks \['exp_avg'\]"),
    (_set(("learner", "optimizer", "param_groups"), []), "holds 0 parameter group"),
    (_set(("learner", "networks", "actor_network_params.module.0.weight"), torch.zeros(2)),
     r"learner.networks.actor_network_params.module.0.weight is torch.float32 \[2\]"),
    (lambda s: next(iter(s["learner"]["networks"].values())).fill_(math.nan),
     "learner.networks.* holds a NaN or infinite value"),
    # counters: frames=NaN read as a finished run (rc 0)
    (_set(("counters", "frames"), math.nan), r"counters.frames=nan is not a count >= 0"),
    (_set(("counters", "updates"), 1.5), r"counters.updates=1.5 is not a count"),
    (_set(("wall_s",), math.nan), "wall_s=nan is not a finite number of seconds"),
    (_set(("learner", "target_counter"), KeyError), r"lacks the field\(s\) \['learner.target_counter'\]"),
    (_set(("counters",), KeyError), r"lacks the field\(s\) \['counters'\]"),
    (_set(("eval_history",), lambda h: [{**h[0], "return": math.inf}]), "eval_history.0. holds"),
    (_set(("rng", "torch"), torch.zeros(3, dtype=torch.uint8)), "rng: its torch state has shape"),
    (_set(("rng", "python"), (3, (1, 2), None)), "rng: its python or numpy state does not load"),
    (_set(("beta_schedule", "initial_val"), math.nan), "beta_schedule holds .'initial_val': nan"),
]  # fmt: skip


@pytest.mark.parametrize(("tamper", "message"), TAMPERS)
def test_a_crafted_checkpoint_is_refused_naming_the_file_and_field_before_restoring(
    saved, tamper, message
):
    state = _state(saved)
    tamper(state)
    resumed = Trainer(tiny_config(saved, total_frames=500, resume=True), toy_env)
    before = [p.detach().clone() for p in resumed.learner.loss.parameters()]
    with pytest.raises(CheckpointSchemaError, match=message) as err:
        resumed.load_state_dict(state)
    text = str(err.value)
    assert "\n" not in text and text.startswith(str(saved / "checkpoint.pt"))
    assert text.endswith("it cannot be resumed")
    after = list(resumed.learner.loss.parameters())
    assert all(torch.equal(a, b) for a, b in zip(before, after, strict=True))  # nothing restored


def test_a_nan_frame_count_in_a_finished_run_is_refused_not_read_as_finished(saved, tmp_path):
    """The finding: ``counters.frames=NaN`` made ``gentlerl train resume=true`` exit 0, done."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(saved, run)
    state = _state(run)
    state["counters"]["frames"] = math.nan
    save_checkpoint(run / "checkpoint.pt", state)
    trainer = Trainer(tiny_config(run, total_frames=500, resume=True), toy_env)
    with pytest.raises(CheckpointSchemaError, match="counters.frames=nan is not a count"):
        trainer.run()


def test_a_wrong_shaped_moment_is_one_line_from_gentlerl_train_not_a_native_abort(saved, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(saved, run)
    state = _state(run)
    _moment(state).update(exp_avg=torch.zeros(7, 5))
    save_checkpoint(run / "checkpoint.pt", state)
    (run / "DONE").unlink()
    code = (
        "import sys; from gentlerl.training import train; from tests.helpers import tiny_config, "
        f"toy_env; train(tiny_config({str(run)!r}, total_frames=600, resume=True), toy_env)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr  # a Python error, not rc 134 / -11
    assert "CheckpointSchemaError" in proc.stderr and "exp_avg has shape [7, 5]" in proc.stderr


def test_a_learning_rate_changed_on_resume_is_applied_to_the_optimisers(saved):
    """The finding: config.yaml recorded the new rate, Adam kept the checkpoint's."""
    resumed = Trainer(
        tiny_config(
            saved, total_frames=500, resume=True,
            learner={"lr_actor": 2e-4, "lr_critic": 5e-4}, gentleness={"lr_model": 7e-4},
        ),
        toy_env,
    )  # fmt: skip
    resumed.load_state_dict(_state(saved))
    assert [g["lr"] for g in resumed.learner.optimizer.param_groups] == [2e-4, 5e-4]
    assert [g["lr"] for g in resumed.rewards.steps["penalty"].optimizer.param_groups] == [7e-4]
    state = _state(saved)  # the moments themselves are the checkpoint's
    got = resumed.learner.optimizer.state_dict()["state"][0]["exp_avg"][0]
    assert torch.equal(got, state["learner"]["optimizer"]["state"][0]["exp_avg"])


def test_a_checkpoint_without_its_config_is_one_line_naming_the_file(saved, tmp_path):
    from gentlerl.training.resume import load_resume_state

    state = _state(saved)
    del state["config"]
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    cfg = tiny_config(tmp_path, total_frames=500, resume=True)
    with pytest.raises(ValueError, match=r"checkpoint.pt: it lacks its config \(a mapping\)"):
        load_resume_state(cfg, tmp_path / "checkpoint.pt")


def test_a_nan_frame_count_in_a_policy_file_is_one_line_naming_it(saved, tmp_path):
    """``gentlerl evaluate`` / ``export`` read a checkpoint's frames as ``int(nan)``."""
    from gentlerl.training.checkpoint import CheckpointError, export_policy

    state = _state(saved)
    state["counters"]["frames"] = math.nan
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    with pytest.raises(CheckpointError, match=r"checkpoint.pt: its frame count nan is not a whole"):
        export_policy(tmp_path / "checkpoint.pt", tmp_path / "policy.pt")
    assert not (tmp_path / "policy.pt").exists()
