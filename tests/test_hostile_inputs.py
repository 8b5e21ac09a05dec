"""Hostile inputs and faults (issue 23): each probe refused in one line, nothing written where it
must not be, and safety checks that fail closed."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import torch

from gentlerl import keys
from gentlerl.apps.sweeps import main as sweep
from gentlerl.envs.watchdog import ForceWatchdog


def _sweep_file(tmp_path: Path, body: str) -> str:
    path = tmp_path / "evil.yaml"
    path.write_text(body)
    return str(path)


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


# --- sweep files cannot run code or write outside --out -------------------------------------


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("+hydra.callbacks.a._target_", "numpy.savetxt"),
        ("hydra.run.dir", "x"),
        ("_target_", "builtins.open"),
        ("++seed", 1),
        ("+foo", 1),
        ("not_a_field", 1),
        ("network", 1),
        ("env.kwargs", 1),
        ("run_dir", "x"),
    ],
)
def test_sweep_keys_must_be_config_fields(tmp_path, key, value, capsys):
    path = _sweep_file(tmp_path, f"parameters:\n  '{key}': {{values: [{value}]}}\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as err:
        sweep([path, "--out", str(out)])
    message = str(err.value.code)
    assert repr(key) in message and "\n" not in message
    assert not out.exists()


def test_a_sweep_callback_payload_writes_nothing(tmp_path):
    target = tmp_path / "pwned.txt"
    body = (
        "parameters:\n  seed: {values: [0]}\n"
        f"  +hydra.callbacks.a._target_: {{value: numpy.savetxt}}\n"
        f"  +hydra.callbacks.a._args_: {{value: ['{target}', [1, 2]]}}\n"
    )
    with pytest.raises(SystemExit, match="hydra"):
        sweep([_sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert not target.exists()


@pytest.mark.parametrize(
    "value",
    ["r/../../../../x", "..", "a b", "${oc.env:HOME}", "r,x", "x=y", "'q'", "/abs"],
)
def test_sweep_values_cannot_leave_out(tmp_path, value):
    path = _sweep_file(tmp_path, f"parameters:\n  variant: {{values: [{value!r}]}}\n")
    before = _files(tmp_path)
    with pytest.raises(SystemExit, match="string value may hold only"):
        sweep([path, "--out", str(tmp_path / "out"), "--dry-run"])
    assert _files(tmp_path) == before


@pytest.mark.parametrize(
    ("body", "match"),
    [
        (f"parameters: {{variant: {{values: [{'r' * 300}]}}}}\n", "longer than 255 bytes"),
        ("", "expected a mapping"),
        ("- a\n- b\n", "expected a mapping"),
        ("parameters: [1, 2]\n", "must be a mapping"),
        ("parameters: {seed: {values: []}}\n", "needs `values:`"),
        ("parameters: {seed: 3}\n", "needs `values:`"),
        ("parameters: {seed: {values: [[[1]]]}}\n", "nested lists"),
        ("parameters: {seed: {values: [{a: 1}]}}\n", "expected a number"),
        ("parameters: {seed: [\n", "not valid YAML"),
    ],
)
def test_malformed_sweep_files_are_one_line_refusals(tmp_path, body, match):
    with pytest.raises(SystemExit, match=match) as err:
        sweep([_sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert "\n" not in str(err.value.code)


def test_missing_sweep_file_and_bad_set_are_refused(tmp_path):
    with pytest.raises(SystemExit, match="No such file"):
        sweep([str(tmp_path / "none.yaml"), "--out", str(tmp_path)])
    good = _sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    for item in ("hydra.job.chdir=true", "+hydra.callbacks.a._target_=os.system", "seed"):
        with pytest.raises(SystemExit, match="--set"):
            sweep([good, "--out", str(tmp_path / "o"), "--set", item, "--dry-run"])
    assert sweep([good, "--out", str(tmp_path / "o"), "--dry-run", "--set",
                  "+env.kwargs.regime=easy"]) == 0  # fmt: skip


# --- the watchdog and the sensor map fail closed ------------------------------------------


def _linear_sensor_map(n_knots: int = 16):
    from gentlerl.transforms import TouchSensorMap

    force = np.linspace(0, 20, 64)[:, None, None] * np.ones((1, 5, 1))
    sensor_map = TouchSensorMap(n_knots=n_knots)
    sensor_map.fit(1000 + 100 * force, force)
    return sensor_map, force


@pytest.mark.parametrize(
    "touch",
    [np.full((5, 1), np.nan), np.full((5, 1), np.inf), np.full((5, 1), -50.0), np.zeros((0,))],
)
def test_the_watchdog_trips_on_readings_it_cannot_trust(touch):
    watchdog = ForceWatchdog(fingertip_limit=3.0)
    assert watchdog.check(touch, None)
    assert watchdog.counts()["fault_trips"] == 1 and watchdog.trips == 1
    assert not watchdog.check(np.zeros((5, 1)), None)


@pytest.mark.parametrize("block", [float("nan"), None, -50.0])
def test_the_block_watchdog_trips_on_a_missing_or_implausible_force(block):
    watchdog = ForceWatchdog(fingertip_limit=None, block_limit=5.0)
    assert watchdog.check(np.zeros((5, 1)), block) and watchdog.fault_trips == 1


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda c: c.force_knots.fill_(float("nan")), "must be finite"),
        (lambda c: c.force_knots.zero_(), "spans 0 N"),
        (lambda c: c.force_knots.copy_(c.force_knots.flip(-1)), "must not decrease"),
        (lambda c: c.raw_knots.fill_(1.0), "strictly increasing"),
        (lambda c: c.raw_zero.fill_(float("inf")), "raw_zero must be finite"),
        (lambda c: c.fitted.fill_(False), "never fitted"),
    ],
)
def test_a_tampered_sensor_map_file_is_refused_on_load(tmp_path, edit, match):
    from gentlerl.transforms import TouchSensorMap

    sensor_map, _ = _linear_sensor_map()
    edit(sensor_map)
    path = tmp_path / "cal.pt"
    sensor_map.save(path)
    with pytest.raises(ValueError, match=match):
        TouchSensorMap.load(path)


def test_a_blinding_sensor_map_cannot_reach_the_driver_env(driver_env):
    from gentlerl.envs import SimulatedDriver

    sensor_map, _ = _linear_sensor_map()
    sensor_map.force_knots.zero_()
    with pytest.raises(ValueError, match="spans 0 N"):
        driver_env(SimulatedDriver(seed=0), "touch", sensor_map=sensor_map)


@pytest.mark.parametrize(
    "content", [b"", b"not a torch file", None], ids=["empty", "garbage", "truncated"]
)
def test_empty_truncated_or_foreign_sensor_map_files_are_refused(tmp_path, content):
    from gentlerl.transforms import TouchSensorMap

    path = tmp_path / "cal.pt"
    if content is None:
        _linear_sensor_map()[0].save(path)
        content = path.read_bytes()[:200]
    path.write_bytes(content)
    with pytest.raises(ValueError, match="is not a TouchSensorMap file"):
        TouchSensorMap.load(path)
    torch.save({"shape": (5, 1), "n_knots": 10**9, "state": {}}, path)
    with pytest.raises(ValueError, match="not a hand's sensor map"):
        TouchSensorMap.load(path)


def test_fit_refuses_dead_inverted_and_unbounded_channels():
    from gentlerl.transforms import TouchSensorMap

    _, force = _linear_sensor_map()
    with pytest.raises(ValueError, match="dead channel"):
        TouchSensorMap(n_knots=8).fit(np.full_like(force, 1000.0), force)
    with pytest.raises(ValueError, match="inverted"):
        TouchSensorMap(n_knots=8).fit(3000 - 100 * force, force)
    for span in (float("nan"), -1.0, 0.0, "1"):
        with pytest.raises(ValueError, match="min_span"):
            TouchSensorMap(n_knots=8).fit(1000 + 100 * force, force, min_span=span)


def test_forward_map_refuses_non_finite_raw_readings():
    sensor_map, _ = _linear_sensor_map()
    for value in (-np.inf, np.inf, np.nan):
        with pytest.raises(ValueError, match="must be finite"):
            sensor_map.forward_map(np.full((5, 1), value))


class _StallingDriver:
    """A scripted driver whose ``read`` stalls from the ``stall_at``-th read on."""

    def __init__(self, stall_at: int, block: float | None = None) -> None:
        from gentlerl.envs.driver import DriverSpec

        self.spec = DriverSpec(-np.ones(20), np.ones(20), has_block_force=block is not None)
        self.reads, self.stall_at, self.block = 0, stall_at, block
        self.commands: list[np.ndarray] = []
        self.release = threading.Event()

    def reset(self) -> np.ndarray:
        return np.zeros(20)

    def read(self):
        from gentlerl.envs.driver import HandReading

        self.reads += 1
        if self.reads >= self.stall_at:
            self.release.wait(5.0)
        return HandReading(np.zeros(24), np.zeros(24), np.full((5, 1), 1000.0), self.block)

    def command(self, targets: np.ndarray) -> None:
        self.commands.append(np.array(targets))

    def close(self) -> None:
        self.release.set()


def test_a_stalled_read_ends_the_episode_safely_and_says_so(driver_env):
    from gentlerl.envs.driver import DriverTimeout

    driver = _StallingDriver(stall_at=4)  # tare + reset read, one step, then a stall
    env = driver_env(driver, "touch", sensor_map=_linear_sensor_map()[0], read_timeout=0.2)
    td = env.reset()
    td = env.step(td.set(keys.ACTION, torch.ones(20)))["next"]
    held = driver.commands[-1]
    with pytest.warns(RuntimeWarning, match="no reading within 0.2 s: episode ended"):
        out = env.step(td.set(keys.ACTION, torch.ones(20)))["next"]
    assert out[keys.TERMINATED].item() and out[keys.WATCHDOG].item() and env.read_timeouts == 1
    np.testing.assert_allclose(driver.commands[-1], held)  # the last targets, re-commanded
    with pytest.raises(DriverTimeout, match="still stalled"):
        env.reset()
    driver.release.set()
    for bad in (0, -1.0, float("nan"), "1"):
        with pytest.raises(ValueError, match="read_timeout"):
            driver_env(_StallingDriver(99), sensor_map=_linear_sensor_map()[0], read_timeout=bad)


def test_an_implausible_block_force_is_refused(driver_env):
    env = driver_env(_StallingDriver(99, block=-50.0), sensor_map=_linear_sensor_map()[0])
    with pytest.raises(ValueError, match="'block_force'=-50.0 N is implausible"):
        env.reset()


# --- a policy file cannot demand an allocation; its sizes must match its weights -------------


def _policy_file(tmp_path: Path, hidden: list[int], weights_hidden: list[int]) -> Path:
    from gentlerl.models import make_actor
    from gentlerl.training.checkpoint import save_checkpoint
    from gentlerl.training.config import preset_config

    config = preset_config(network={"actor_hidden": hidden}).to_dict()
    actor = make_actor(10, 20, weights_hidden)
    path = tmp_path / "policy.pt"
    state = {"config": config, "obs_dim": 10, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(path, state)
    return path


def test_a_policy_demanding_a_huge_actor_is_refused_before_allocating(tmp_path):
    from gentlerl.training.checkpoint import CheckpointError, load_policy

    path = _policy_file(tmp_path, [200000, 200000], [16])
    with pytest.raises(CheckpointError, match=r"actor_hidden=\[200000, 200000\]: each value must"):
        load_policy(path)


def test_a_policy_whose_config_and_weights_disagree_is_one_line(tmp_path):
    from gentlerl.training.checkpoint import CheckpointError, load_policy

    with pytest.raises(CheckpointError) as err:
        load_policy(_policy_file(tmp_path, [32], [16]))
    assert "\n" not in str(err.value) and "policy.pt" in str(err.value)
    assert len(load_policy(_policy_file(tmp_path, [16], [16]))) == 2


# --- one writer per run directory; faults leave the run resumable -----------------------------


def test_a_run_directory_has_one_writer(tmp_path):
    from gentlerl.training.run_lock import RunLock, RunLockedError

    run_dir = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_LOCK, str(run_dir)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunLockedError, match=f"in use by pid {holder.pid} on ") as err:
            RunLock(run_dir).acquire()
        assert "\n" not in str(err.value)
    finally:
        holder.kill()
        holder.wait()
    # The holder was killed: its lock is stale and taken over.
    assert (run_dir / ".lock").read_text().startswith(f"pid {holder.pid}")
    with RunLock(run_dir):
        assert (run_dir / ".lock").read_text().startswith(f"pid {os.getpid()}")
    assert not run_dir.exists() or not (run_dir / ".lock").exists()


HOLD_LOCK = """
import sys, time
from gentlerl.training.run_lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("locked", flush=True)
time.sleep(60)
"""


def test_train_refuses_a_locked_run_dir_before_writing(tmp_path):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train
    from gentlerl.training.run_lock import RunLock, RunLockedError

    run_dir = tmp_path / "run"
    with RunLock(run_dir):
        before = _files(tmp_path)
        with pytest.raises(RunLockedError, match="is in use by"):
            train(make_config(run_dir=str(run_dir), resume="auto"))
        assert _files(tmp_path) == before


def test_a_refused_run_leaves_no_empty_run_dir(tmp_path):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    run_dir = tmp_path / "run"
    with pytest.raises(ValueError, match="resume=true but there is no checkpoint"):
        train(make_config(run_dir=str(run_dir), resume=True))
    assert not run_dir.exists()


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


def test_a_ray_run_without_a_cluster_writes_nothing(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    from gentlerl.distributed import ClusterError
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    cfg = make_config(
        run_dir=str(tmp_path / "run"), collector={"kind": "ray", "ray_address": "auto"}
    )
    with pytest.raises(ClusterError, match="no Ray cluster found"):
        train(cfg)
    assert list(tmp_path.iterdir()) == []


# --- silent acceptances and crashes turned into one-line refusals --------------------------


@pytest.mark.parametrize(
    ("cls", "lam"),
    [
        ("ImpactPenalty", (float("nan"), 2.0)),
        ("ImpactPenalty", (2.0, -5.0)),
        ("ImpactPenalty", (2.0,)),
        ("ImpactPenalty", (-1.0, 2.0)),
        ("ImpactPenalty", "ab"),
        ("ForcePenalty", (float("nan"), 8.0)),
        ("ForcePenalty", (2.0, float("inf"))),
        ("TorquePenalty", (1.0, 2.0, 3.0)),
    ],
)
def test_bad_lambdas_are_refused(cls, lam):
    import gentlerl.transforms as transforms

    with pytest.raises(ValueError, match=f"{cls} lam must be two finite numbers"):
        getattr(transforms, cls)(lam=lam)


def test_transforms_name_a_missing_next_or_key():
    from tensordict import TensorDict

    from gentlerl.transforms import ForcePenalty, ImpactPenalty

    with pytest.raises(ValueError, match="needs a transition: a tensordict with a 'next' entry"):
        ImpactPenalty()(TensorDict({"touch": torch.zeros(5, 3)}))
    td = TensorDict({"force": torch.zeros(5, 3), "next": {"force": torch.zeros(5, 3)}})
    for transform in (ImpactPenalty(), ForcePenalty()):
        with pytest.raises(ValueError, match="reads 'touch', which the tensordict lacks"):
            transform(td.clone())
    td = TensorDict({"touch": torch.zeros(5, 3), "next": {"touch": torch.zeros(4, 3)}})
    with pytest.raises(ValueError, match=r"must be \[..., n_sites, n_channels\] at both steps"):
        ImpactPenalty()(td)


def _fake_run(root: Path, seed: int = 0, scalars: str | None = "1000,0.5\n2000,0.7\n") -> Path:
    import yaml

    run = root / f"seed{seed}"
    config = {"task": "touch", "variant": "r", "seed": seed, "collector": {}, "gentleness": {}}
    run.mkdir(parents=True)
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    if scalars is not None:
        (run / "logs" / "scalars" / "eval").mkdir(parents=True)
        (run / "logs" / "scalars" / "eval" / "success_rate.csv").write_text(scalars)
    return run


@pytest.mark.parametrize(
    ("file", "content", "match"),
    [
        ("logs/scalars/eval/success_rate.csv", "1000,0.5\nnot,a,number\n", "success_rate.csv:2"),
        ("config.yaml", "task: [unclosed\n", "config.yaml: not valid YAML"),
        ("config.yaml", "- a list\n", "config.yaml: not a run's config"),
    ],
)
def test_plot_names_a_malformed_file_and_writes_nothing(tmp_path, file, content, match):
    from gentlerl.apps.plot import main as plot

    run = _fake_run(tmp_path / "runs")
    (run / file).write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert "\n" not in str(err.value) and not (tmp_path / "figs").exists()


def test_plot_skips_runs_that_logged_nothing_instead_of_nan_rows(tmp_path, capsys):
    from gentlerl.apps.plot import main as plot

    _fake_run(tmp_path / "runs", seed=0, scalars=None)
    with pytest.raises(FileNotFoundError, match="none of the 1 run"):
        plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert not (tmp_path / "figs").exists()
    _fake_run(tmp_path / "runs", seed=1)
    plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert "skipped 1 run(s) with nothing logged" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ('{"policy": "x/checkpoint.pt"}\n', "lacks 'success_rate'"),
        ("not json\n", "is not a JSON object"),
        ("[1, 2]\n", "is not a JSON object"),
        (
            '{"policy": "x/checkpoint.pt", "success_rate": 7}\n',
            r"success_rate=7.0 is not in \[0, 1\]",
        ),
    ],
)
def test_claims_refuses_a_bad_final_eval_file(tmp_path, content, match):
    from gentlerl.apps.claims import main as claims

    evals = tmp_path / "evals" / "sweep"
    evals.mkdir(parents=True)
    (evals / "final_eval.jsonl").write_text(content)
    _fake_run(tmp_path / "runs")
    with pytest.raises(ValueError, match=f"final_eval.jsonl:1.*{match}"):
        claims([str(tmp_path / "runs"), "--final-evals", str(tmp_path / "evals")])


def test_claims_refuses_a_missing_final_evals_folder(tmp_path):
    from gentlerl.apps.claims import main as claims

    _fake_run(tmp_path / "runs")
    for folder in (tmp_path / "nonexistent", tmp_path / "runs"):
        with pytest.raises(FileNotFoundError, match="--final-evals"):
            claims([str(tmp_path / "runs"), "--final-evals", str(folder)])


def test_export_refuses_unknown_tasks_and_an_empty_export(tmp_path, capsys):
    from gentlerl.apps.export import main as export

    with pytest.raises(SystemExit):
        export([str(tmp_path), "--tasks", "bogus"])
    assert "invalid choice: 'bogus'" in capsys.readouterr().err


def test_evaluate_checks_its_csv_and_seed_before_any_episode(tmp_path):
    from gentlerl.apps.evaluate import evaluate_policy

    missing = tmp_path / "no_policy.pt"  # never reached: the output is checked first
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(IsADirectoryError, match="is a directory"):
        evaluate_policy(missing, 1, episodes_csv=tmp_path / "dir.csv")
    with pytest.raises(ValueError, match="must end in .csv"):
        evaluate_policy(missing, 1, episodes_csv=tmp_path / "out.txt")
    for seed in (-1, 2**32):
        with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*32\)"):
            evaluate_policy(missing, 1, seed=seed)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.csv"]


def test_video_checks_its_output_before_rendering(tmp_path):
    from gentlerl.apps.video import main as video

    missing = str(tmp_path / "no_policy.pt")
    (tmp_path / "dir.mp4").mkdir()
    read_only = tmp_path / "ro"
    read_only.mkdir(mode=0o555)
    cases = [("out.avi", ValueError, "must end in .mp4 or .gif"), ("dir.mp4", OSError, "directory")]
    if os.geteuid() != 0:  # root writes anywhere
        cases.append(("ro/out.mp4", PermissionError, "not writable"))
    for out, error, match in cases:
        with pytest.raises(error, match=match):
            video([missing, "-o", str(tmp_path / out)])
    assert not list(tmp_path.rglob("*.tmp*"))


def test_an_empty_config_history_does_not_crash_a_resume(tmp_path):
    from gentlerl.config.layout import CONFIG_HISTORY
    from gentlerl.training.guards import record_config_changes

    (tmp_path / CONFIG_HISTORY).write_text("")
    state = {"counters": {"frames": 10}, "config": {"seed": 0, "logging": {"eval_episodes": 1}}}
    now = {"seed": 0, "logging": {"eval_episodes": 2}}
    assert record_config_changes(tmp_path, state, now) == ["logging.eval_episodes"]
    (tmp_path / CONFIG_HISTORY).write_text("a: mapping\n")
    with pytest.raises(ValueError, match="must be a YAML list"):
        record_config_changes(tmp_path, state, now)


# --- sweeps: interrupted points resume, an interrupted sweep leaves no trainer behind ---------

SPAWNING_RECIPE = """
import subprocess, sys, time
from pathlib import Path
run_dir = Path(next(a for a in sys.argv if a.startswith("run_dir="))[8:])
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
(run_dir / "pids").write_text(f"{child.pid}\\n")
time.sleep(120)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie is dead too
        return f.read().split(")")[-1].split()[0] != "Z"


def test_an_interrupted_sweep_kills_its_trainers_process_groups(tmp_path):
    import dataclasses
    import signal
    import time

    from gentlerl.apps.grid import expand, run_grid

    script = tmp_path / "spawning.py"
    script.write_text(SPAWNING_RECIPE)
    grid = expand({"seed": [0, 1]}, tmp_path / "g")
    runs = [dataclasses.replace(r, script=script) for r in grid]
    pids = runs[0].run_dir / "pids"

    def ctrl_c_once_the_trainer_runs() -> None:
        for _ in range(400):
            if pids.exists() and pids.read_text().endswith("\n"):
                break
            time.sleep(0.05)
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C: KeyboardInterrupt in the main thread

    # Ctrl-C raises KeyboardInterrupt even where pytest inherited SIGINT ignored (a shell starts
    # background jobs so, and Python then keeps it ignored).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=ctrl_c_once_the_trainer_runs, daemon=True).start()
        with pytest.raises(KeyboardInterrupt):
            run_grid(runs, workers=1)
    finally:
        signal.signal(signal.SIGINT, previous)
    grandchild = int(pids.read_text())
    for _ in range(100):
        if not _alive(grandchild):
            break
        time.sleep(0.05)
    assert not _alive(grandchild)  # the trainer's own child too: its whole group
    assert not (runs[1].run_dir / "stdout.log").exists()  # the queued point never started


def test_a_point_interrupted_before_its_first_checkpoint_resumes(tmp_path):
    from gentlerl.apps.sweeps import main as sweep

    from .test_sweeps import TINY

    path = _sweep_file(tmp_path, "parameters:\n  variant: {values: [r]}\n  seed: {values: [0]}\n")
    run = tmp_path / "out" / "evil" / "variant-r_seed-0"
    (run / "logs" / "scalars").mkdir(parents=True)  # what a point killed early leaves
    (run / "config.yaml").write_text("task: touch\n")
    args = [path, "--out", str(tmp_path / "out"), *sum((["--set", o] for o in TINY), [])]
    assert sweep(args) == 0
    assert (run / "DONE").exists() and (run / "checkpoint.pt").exists()


# --- the gentlerl command: one line per refusal, the traceback only when asked ----------------


def test_a_refusal_is_one_line_on_stderr_and_exit_1(tmp_path, capsys, monkeypatch):
    from gentlerl.cli import main

    monkeypatch.setenv("GENTLERL_DEBUG", "0")  # restored afterwards, also after --debug sets it
    assert main(["evaluate", str(tmp_path / "none.pt")]) == 1
    err = capsys.readouterr().err
    assert err == f"gentlerl evaluate: error: no checkpoint at {tmp_path / 'none.pt'}\n"
    with pytest.raises(FileNotFoundError):
        main(["evaluate", str(tmp_path / "none.pt"), "--debug"])
    monkeypatch.setenv("GENTLERL_DEBUG", "1")
    with pytest.raises(FileNotFoundError):
        main(["plot", str(tmp_path / "none")])


def test_an_unexpected_error_names_its_type_and_the_debug_switch():
    from gentlerl.apps.errors import one_line

    assert one_line(ValueError("invalid:\n  - a\n  - b")) == "invalid: a; b"
    assert one_line(KeyError("x")) == "KeyError: 'x' (GENTLERL_DEBUG=1 shows the traceback)"


def test_train_refuses_unknown_fields_in_one_line(monkeypatch):
    from gentlerl.cli import main

    with pytest.raises(SystemExit, match=r"unknown config field\(s\) \['foo', 'network.bogus'\]"):
        main(["train", "foo=1", "network.bogus=2", "seed=1", "+env.kwargs.regime=easy"])


def test_video_without_an_opengl_backend_says_what_to_install(tmp_path, monkeypatch):
    from gentlerl.apps.video import main as video

    monkeypatch.setenv("MUJOCO_GL", "disable")  # what gentlerl.envs sets when none can load
    with pytest.raises(SystemExit, match="MUJOCO_GL=egl.*apt-get install libosmesa6"):
        video([str(tmp_path / "none.pt"), "-o", str(tmp_path / "v.mp4")])


def test_a_ctrl_c_masked_by_a_library_error_still_reads_as_interrupted():
    from gentlerl.apps.errors import interrupted

    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("Converting a tensordict to boolean value is not permitted")  # noqa: B904
    except RuntimeError as err:
        masked = err
    assert interrupted(masked) and not interrupted(RuntimeError("a real bug"))


@pytest.mark.parametrize(
    ("parameters", "match"),
    [
        ("seed: {values: [0, -1]}", r"grid point seed--1: seed=-1 must be in \[0, 2\*\*32\)"),
        ("seed: {values: [4294967296]}", r"seed=4294967296 must be in \[0, 2\*\*32\)"),
        ("variant: {values: [bogus]}", "variant='bogus' is not one of"),
        ("gentleness.lam_prime: {values: [[2]]}", "gentleness.lam_prime=.* must have 2 values"),
    ],
)
def test_every_sweep_point_is_validated_before_any_runs(tmp_path, parameters, match):
    path = _sweep_file(tmp_path, f"parameters:\n  {parameters}\n")
    with pytest.raises(SystemExit, match=match) as err:
        sweep([path, "--out", str(tmp_path / "out")])
    assert "\n" not in str(err.value.code) and not (tmp_path / "out").exists()


def test_export_cannot_be_steered_outside_out_by_a_policy_config(tmp_path):
    from gentlerl.apps.export import main as export
    from gentlerl.training.checkpoint import CheckpointError, load_checkpoint, save_checkpoint

    path = _policy_file(tmp_path, [16], [16])
    state = load_checkpoint(path)
    state["config"]["variant"] = "../../../escaped"
    save_checkpoint(tmp_path / "checkpoint.pt", state)
    with pytest.raises(CheckpointError, match="variant='../../../escaped' is not one of"):
        export([str(tmp_path / "checkpoint.pt"), "--out", str(tmp_path / "out")])
    assert not list(tmp_path.parent.glob("escaped*")) and not (tmp_path / "out").exists()


def test_a_penalty_model_names_a_missing_or_wrongly_sized_observation():
    import torch
    from tensordict import TensorDict

    from gentlerl.models import PenaltyModel

    model = PenaltyModel(4, 2, 3, (8, 8, 8))
    with pytest.raises(ValueError, match=r"'observation' of size 4, got shape \(5, 7\)"):
        model.predict(
            TensorDict({"observation": torch.zeros(5, 7), "action": torch.zeros(5, 2)}, [5])
        )
    with pytest.raises(KeyError, match="'action'"):
        model.predict(TensorDict({"observation": torch.zeros(5, 4)}, [5]))


# --- issue 32: no sweep reaches a cluster, every size bounded, one line, checked up front -----


@pytest.mark.parametrize(
    ("parameters", "allowed"),
    [
        ("collector.kind: {value: ray}\n  collector.ray_address: {value: evil.example:6379}", None),
        ("collector.ray_address: {value: evil.example:6379}", "applies to collector.kind=ray only"),
        ("collector.kind: {values: [single, ray]}", None),
    ],
)
def test_a_sweep_file_cannot_send_its_runs_to_a_ray_cluster(tmp_path, parameters, allowed, capsys):
    path = _sweep_file(tmp_path, f"parameters:\n  {parameters}\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as err:
        sweep([path, "--out", str(out), "--dry-run"])
    message = str(err.value.code)
    assert "a sweep does not choose where its runs execute" in message and "\n" not in message
    assert "--allow-ray-collector" in message and "collector." in message
    assert "gentlerl.apps.train" not in capsys.readouterr().out  # nothing planned
    assert not out.exists()
    # the command line may allow it: then the point is planned (once its config is valid)
    allow = [path, "--out", str(out), "--dry-run", "--allow-ray-collector"]
    if allowed is None:
        assert sweep(allow) == 0
    else:
        with pytest.raises(SystemExit, match=allowed):
            sweep(allow)


@pytest.mark.parametrize(
    ("item", "match"),
    [
        ("logging.wandb_project=${oc.env:HOME}", "string value may hold only"),
        ("+env.kwargs.regime=${oc.env:HOME}", "string value may hold only"),
        ("collector.kind=ray", "a sweep does not choose where its runs execute"),
        ("collector.ray_address=evil.example:6379", "a sweep does not choose where"),
        ("seed=[1", "not a plain number, name or list"),
        ("seed={a: 1}", "expected a number, a name or a list"),
    ],
)
def test_set_follows_the_sweep_files_rules(tmp_path, item, match):
    good = _sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    with pytest.raises(SystemExit, match=match) as err:
        sweep([good, "--out", str(tmp_path / "o"), "--set", item, "--dry-run"])
    assert f"--set {item!r}" in str(err.value.code) and "\n" not in str(err.value.code)


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


@pytest.mark.parametrize(
    ("group", "name", "value"),
    [
        ("network", "critic_hidden", [100000, 100000]),
        ("gentleness", "ensemble_size", 1000000),
        ("gentleness", "model_hidden", 1000000),
    ],
)
def test_calibration_refuses_a_checkpoint_of_huge_sizes_before_building(
    tmp_path, group, name, value
):
    from gentlerl.apps.calibration import critic_calibration
    from gentlerl.models import make_actor
    from gentlerl.training.checkpoint import save_checkpoint
    from gentlerl.training.config import preset_config

    config = preset_config().to_dict()
    config[group][name] = value
    state = {"config": config, "obs_dim": 63, "action_dim": 20, "learner": {}, "intrinsic": {}}
    save_checkpoint(tmp_path / "checkpoint.pt", {**state, "actor": make_actor(63, 20).state_dict()})
    with pytest.raises(
        ValueError, match=rf"its config is invalid: {group}.{name}=.* must be in \["
    ):
        critic_calibration(tmp_path, episodes=1)


def _train(args: list[str]) -> str:
    """``gentlerl train ARGS`` in this process: its refusal (the one line ``SystemExit`` carries)."""
    from gentlerl.cli import main

    with pytest.raises(SystemExit) as err:
        main(["train", *args])
    return str(err.value.code)


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("collector.total_frames=99999999999999999999999", "must be in [1, 10000000000]"),
        ("network.actor_hidden=[200000,200000]", ": each value must be in [1, 4096]"),
        ("num_threads=100000", "num_threads=100000 must be in [1, 256]"),
        ("collector.num_envs=100000", "collector.num_envs=100000 must be in [1, 256]"),
        ("logging.eval_episodes=100000", "logging.eval_episodes=100000 must be in [0, 256]"),
        ("gentleness.ensemble_size=1000000", "gentleness.ensemble_size=1000000 must be in [1, 32]"),
        ("replay.buffer_size=1000000000000", "replay.buffer_size=1000000000000 must be in [1, 1"),
    ],
)
def test_sizes_past_their_limit_are_refused_before_anything_is_written(
    tmp_path, monkeypatch, override, message
):
    monkeypatch.chdir(tmp_path)
    refusal = _train([override])
    assert refusal.startswith("gentlerl train: error: invalid training config: ")
    assert message in refusal and "\n" not in refusal
    assert list(tmp_path.iterdir()) == []


def test_calibration_bounds_its_episodes_and_checks_its_json_before_the_rollouts(tmp_path):
    from gentlerl.apps.calibration import critic_calibration, main

    with pytest.raises(ValueError, match=r"episodes must be an integer in \[1, 256\]"):
        critic_calibration(tmp_path / "none", episodes=100000)
    (tmp_path / "checkpoint.pt").write_bytes(b"")  # never read: the output is checked first
    with pytest.raises(SystemExit) as err:
        main([str(tmp_path), "--json", str(tmp_path / "checkpoint.pt" / "x.json")])
    assert "error: --json " in str(err.value.code) and "is not a directory" in str(err.value.code)


@pytest.mark.parametrize(
    ("env", "match"),
    [
        ({"kwargs": {"bogus": 1}}, "env.kwargs.bogus=1 is not a keyword of the env: cannot build"),
        ({"kwargs": {"frame_skip": 0}}, r"env.kwargs.frame_skip=0 must be an integer >= 1"),
        ({"kwargs": {"device": "cuda:99"}}, r"env.kwargs.device='cuda:99': this machine's torch"),
        (
            {"observation_keys": ["position", "position"]},
            r"env.observation_keys=\['position', 'position'\] names \['position'\] more than",
        ),
        (
            {"force_adapter": "none", "force_key": "position"},
            r"force key 'position' \(env.force_key\) has shape \[4\], not the \[n_sites",
        ),
    ],
)
def test_an_external_envs_settings_are_checked_before_anything_is_written(tmp_path, env, match):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    with pytest.raises(ValueError, match=match) as err:
        cfg = make_config(
            variant="r+rf", run_dir=str(tmp_path / "run"),
            env={"name": "dm_control:finger-spin", **env},
        )  # fmt: skip
        train(cfg)
    assert "\n" not in str(err.value).removeprefix("invalid training config:\n  - ")
    assert list(tmp_path.iterdir()) == []


def test_a_policy_for_another_env_is_refused_naming_both_sizes(tmp_path):
    from gentlerl.apps.evaluate import evaluate_policy

    path = _policy_file(tmp_path, [16], [16])  # obs_dim 10; the touch hand's observation: 63
    with pytest.raises(ValueError, match=r"policy.pt: its actor has obs_dim=10, but this env's "):
        evaluate_policy(path, 1)


@pytest.mark.parametrize(
    ("address", "match"),
    [
        ("127.0.0.1:99999", r"port '99999' is not a number in \[1, 65535\]"),
        ("127.0.0.1:²", r"port '²' is not a number in \[1, 65535\]"),
        ("http://127.0.0.1:1", "no other scheme"),
        ("6379", "'6379' is not a host name or an IP address.*a port alone is not an address"),
        ("999.1.1.1:2", "'999.1.1.1' is not a host name or an IP address"),
    ],
)
def test_ray_addresses_that_are_not_addresses_are_refused_by_the_config(address, match):
    from gentlerl.training.config import make_config

    with pytest.raises(ValueError, match=f"collector.ray_address='{re.escape(address)}'.*{match}"):
        make_config(collector={"kind": "ray", "ray_address": address})


def test_a_bracketed_ipv6_ray_address_is_parsed_and_probed():
    from gentlerl.distributed.cluster import ClusterError, check_reachable, parse_address

    assert parse_address("[::1]:1") == ("::1", 1)
    assert parse_address("ray://head.example") == ("head.example", 10001)
    with pytest.raises(ClusterError, match=r"cannot reach the Ray cluster at '\[::1\]:1'"):
        check_reachable("[::1]:1", timeout=2.0)


@pytest.mark.parametrize(
    ("override", "message"),
    [
        *[
            (f"collector.total_frames={v}", f"collector.total_frames={v} must be an integer")
            for v in ("abc", "1.5", "[1,2]", "{a: 1}", "true")
        ],
        ("env.force_scale=abc", "env.force_scale=abc must be a finite number"),
        ("network.actor_hidden=300", "network.actor_hidden=300 must be a list of integers"),
        ("network.actor_hidden=[a,b]", "network.actor_hidden=[a,b] must be a list of integers"),
        ("env.kwargs=5", "env.kwargs=5 must be a mapping"),
        ("resume=1", "resume=1 must be true, false or a string"),
        ("collector.overlap=1", "collector.overlap=1 must be true, false or a string"),
        ("run_dir=" + "x" * 5000, "(5000 chars): a folder name is 5000 bytes, over 255"),
        ("collector.ray_address=[::1]:1", "a string: collector.ray_address='[::1]:1')"),
        ("seed=[1", "seed=[1: "),
        ("+seed=1", "Could not append to config"),
    ],
)
def test_command_line_errors_are_one_line_naming_the_field_and_the_value(
    tmp_path, monkeypatch, capsys, override, message
):
    monkeypatch.chdir(tmp_path)
    refusal = _train([override])
    assert refusal.startswith("gentlerl train: error: ") and message in refusal
    assert "\n" not in refusal and len(refusal) < 300
    assert capsys.readouterr().err == ""  # hydra printed nothing of its own
    assert list(tmp_path.iterdir()) == []


def test_an_interpolation_that_cannot_resolve_is_one_line(tmp_path):
    # In a process of its own: an error resolving the config leaves objects that pytest's
    # capture of this process does not outlive.
    env = {**os.environ, "GENTLERL_DEBUG": "0"}
    env.pop("NOPE_UNSET", None)
    done = subprocess.run(
        [sys.executable, "-m", "gentlerl", "train", "run_dir=${oc.env:NOPE_UNSET}"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    lines = [line for line in done.stderr.splitlines() if "arn" not in line]  # not warnings
    assert done.returncode == 1 and lines[-1].startswith(
        "gentlerl train: error: run_dir=${oc.env:NOPE_UNSET}: "
    ), done.stderr
    assert "Environment variable 'NOPE_UNSET' not found" in lines[-1]
    assert "Traceback" not in done.stderr and "HYDRA_FULL_ERROR" not in done.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("~seed", "~seed: a config field cannot be removed"),
        ("~network", "~network: a config field cannot be removed"),
        ("hydra.run.dir=X", "hydra.run.dir=X: gentlerl sets hydra's folders from run_dir"),
        ("hydra.sweep.dir=X", "hydra.sweep.dir=X: gentlerl sets hydra's folders"),
    ],
)
def test_removing_a_field_or_moving_hydras_folder_is_refused(
    tmp_path, monkeypatch, override, message
):
    monkeypatch.chdir(tmp_path)
    assert message in _train([override])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--backend", "ray", "--cpus-per-run", "0"], "--cpus-per-run=0.0 must be > 0"),
        (["--backend", "ray", "--address", "6379"], "--address '6379': '6379' is not a host"),
        (["--workers", "0"], "--workers=0 must be >= 1"),
    ],
)
def test_sweep_options_are_checked_before_anything_runs(tmp_path, args, message):
    good = _sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    with pytest.raises(SystemExit, match=re.escape(message)):
        sweep([good, "--out", str(tmp_path / "o"), "--dry-run", *args])
    assert not (tmp_path / "o").exists()


def test_a_ray_address_without_the_ray_collector_is_refused():
    from gentlerl.training.config import make_config

    with pytest.raises(ValueError, match="collector.ray_address='127.0.0.1:6379' applies to "):
        make_config(collector={"ray_address": "127.0.0.1:6379"})


def _process_run(tmp_path: Path):
    from gentlerl.training.config import make_config

    from .test_training_loop import TINY, toy_env

    fast = {**TINY["collector"], "overlap": "process", "total_frames": 10**6}
    logging = {**TINY["logging"], "checkpoint_every_frames": 100, "eval_every_frames": 10**6}
    cfg = make_config(**{**TINY, "collector": fast, "logging": logging, "run_dir": str(tmp_path)})
    return cfg, toy_env


def _when_checkpointed(run_dir: Path, then) -> threading.Thread:
    """A thread calling ``then()`` once ``run_dir`` holds a checkpoint (at most 60 s on)."""
    import time

    def wait() -> None:
        for _ in range(1200):
            if (run_dir / "checkpoint.pt").exists():
                break
            time.sleep(0.05)
        then()

    thread = threading.Thread(target=wait, daemon=True)
    thread.start()
    return thread


def test_sigterm_stops_a_process_collector_run_as_ctrl_c_does(tmp_path):
    import multiprocessing
    import signal

    from gentlerl.apps.errors import Terminated, exit_status, sigterm_as_interrupt
    from gentlerl.training.checkpoint import load_checkpoint
    from gentlerl.training.loop import train

    cfg, env = _process_run(tmp_path)
    _when_checkpointed(tmp_path, lambda: os.kill(os.getpid(), signal.SIGTERM))
    with pytest.raises(Terminated) as err, sigterm_as_interrupt():
        train(cfg, env)
    assert exit_status(err.value) == 143 and not multiprocessing.active_children()
    assert not (tmp_path / ".lock").exists()  # the lock released
    assert int(load_checkpoint(tmp_path / "checkpoint.pt")["counters"]["frames"]) >= 100


def test_a_killed_collector_process_says_what_happened_and_that_resume_continues(tmp_path):
    import multiprocessing
    import signal

    from gentlerl.apps.errors import one_line
    from gentlerl.training.loop import train

    def kill_collector() -> None:
        for child in multiprocessing.active_children():
            if child.name == "collector":
                os.kill(child.pid, signal.SIGKILL)

    cfg, env = _process_run(tmp_path)
    _when_checkpointed(tmp_path, kill_collector)
    with pytest.raises(ChildProcessError) as err:
        train(cfg, env)
    message = one_line(err.value)
    assert message.startswith("the collector process was killed by SIGKILL; the last checkpoint")
    assert message.endswith("is intact: rerun with resume=auto to continue")
    assert not (tmp_path / ".lock").exists() and not multiprocessing.active_children()
