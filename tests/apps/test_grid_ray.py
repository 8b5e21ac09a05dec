"""Sweeps on Ray: grid points as tasks on a local 2-CPU Ray, resumed; clear errors without Ray."""

import dataclasses
import socket
import sys
import time

import pytest

from gentlerl.apps.grid import expand
from gentlerl.apps.grid_ray import run_grid_on_ray
from gentlerl.apps.sweeps import main
from gentlerl.distributed import RAY_EXTRA, ClusterError, connect

from .test_sweeps import TINY

ray = pytest.importorskip("ray")

# Stands in for `gentlerl-train` (a real run takes ~20 s here): records its arguments and
# the node's process id, fails for seed=1, and marks the run DONE as the recipe does.
FAKE_RECIPE = """
import os, sys
from pathlib import Path
run_dir = Path(next(a for a in sys.argv if a.startswith("run_dir="))[8:])
print(os.getpid(), *sys.argv[1:])
if "seed=1" in sys.argv:
    raise SystemExit("seed 1 fails")
(run_dir / "DONE").write_text("done")
"""


# These two first: they need Ray not initialised in this process.
def test_an_unreachable_address_is_a_clear_error_within_seconds_and_writes_nothing(tmp_path):
    sweep = tmp_path / "tiny.yaml"
    sweep.write_text("method: grid\nparameters:\n  seed: {values: [0]}\n")
    out = tmp_path / "out"
    address = f"127.0.0.1:{_closed_port()}"
    start = time.perf_counter()
    with pytest.raises(SystemExit, match=f"cannot reach the Ray cluster at '{address}'"):
        main([str(sweep), "--backend", "ray", "--address", address, "--out", str(out)])
    assert time.perf_counter() - start < 30 and not out.exists()
    with pytest.raises(ValueError, match="port 'port' is not a number"):
        with connect("ray://somewhere:port"):
            pass


def test_without_ray_one_line_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(ClusterError, match="pip install -e '.\\[ray\\]'"):
        with connect():
            pass
    sweep = tmp_path / "tiny.yaml"
    sweep.write_text("method: grid\nparameters:\n  seed: {values: [0]}\n")
    with pytest.raises(SystemExit) as exit_:
        main([str(sweep), "--backend", "ray", "--out", str(tmp_path / "out")])
    assert str(exit_.value) == RAY_EXTRA and "\n" not in RAY_EXTRA
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def local_ray():
    """One small local Ray for the module (starting one costs seconds)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # nothing listens there once the socket is closed


def _grid(tmp_path, seeds):
    script = tmp_path / "fake_train.py"
    script.write_text(FAKE_RECIPE)
    runs = expand({"variant": ["r", "r+rf"], "seed": seeds}, tmp_path / "grid")
    return [dataclasses.replace(r, script=script) for r in runs]


def test_grid_points_run_as_tasks_done_skipped_checkpoint_resumed_failure_counted(
    local_ray, tmp_path
):
    runs = _grid(tmp_path, [0, 1])  # r/0, r/1, r+rf/0, r+rf/1
    runs[2].run_dir.mkdir(parents=True)
    (runs[2].run_dir / "DONE").write_text("done\n")
    (runs[0].run_dir).mkdir(parents=True)
    (runs[0].run_dir / "checkpoint.pt").write_bytes(b"x")
    counts = run_grid_on_ray(runs, ["total_frames=300"])
    assert counts == {"skipped": 1, "done": 1, "failed": 2, "planned": 0}
    logs = {r.run_dir.name: (r.run_dir / "stdout.log") for r in runs}
    resumed = logs["variant-r_seed-0"].read_text()
    assert "variant=r seed=0 total_frames=300 resume=auto run_dir=" in resumed
    assert "seed 1 fails" in logs["variant-r_seed-1"].read_text()
    assert not logs["variant-r+rf_seed-0"].exists()  # DONE: never started
    # Second pass: only the two failed runs are tried again.
    assert run_grid_on_ray(runs, [])["skipped"] == 2


def test_each_task_reserves_cpus_per_run(local_ray, tmp_path):
    # 2 CPUs, 2 CPUs per run: the two runs cannot overlap, so two different processes in turn.
    runs = _grid(tmp_path, [0])
    assert run_grid_on_ray(runs, [], cpus_per_run=2)["done"] == 2
    pids = {(r.run_dir / "stdout.log").read_text().split()[0] for r in runs}
    assert len(pids) == 2
    with pytest.raises(ValueError, match="cpus_per_run=0 must be > 0"):
        run_grid_on_ray(runs, [], cpus_per_run=0)


@pytest.mark.slow
def test_a_real_tiny_grid_on_ray_runs_and_resumes(local_ray, tmp_path):
    runs = expand({"variant": ["r"], "seed": [0]}, tmp_path / "grid")
    assert run_grid_on_ray(runs, TINY)["done"] == 1
    assert (runs[0].run_dir / "DONE").exists()
    # Interrupted after its last checkpoint (DONE gone): the task continues it to 600 frames.
    (runs[0].run_dir / "DONE").unlink()
    longer = [o for o in TINY if "total_frames" not in o] + ["collector.total_frames=600"]
    assert run_grid_on_ray(runs, longer)["done"] == 1
    success = runs[0].run_dir / "logs" / "scalars" / "eval" / "success_rate.csv"
    frames = [line.split(",")[0] for line in success.read_text().split()]
    # first run, then resumed from its checkpoint; each final evaluation logged once (the
    # in-loop one at total_frames is the final one: tests/training/test_loop.py's contract)
    assert frames == ["300", "600"]
