"""Hand env speed: TorchRL ``HandEnv`` control steps/s vs raw ``physics.step`` of the same model.

Each control step is ``n_sub_steps`` = 25 MuJoCo steps of 2 ms (50 ms, 20 Hz). Rows:
raw physics (the same 25 sub-steps and random delta-position control, nothing else), the dm_control
environment, the TorchRL env (``env.step`` on a reused tensordict; and with ``step_mdp`` as a\nhand-written loop would), its
``rollout``, and a 2-worker ``ParallelEnv`` (total steps/s). The ``explore`` task is used so that
no episode ends early. Run: ``python benchmarks/env_speed.py [--steps 2000] [--markdown]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from torchrl.envs import ParallelEnv
from torchrl.envs.utils import step_mdp

from gentlerl import keys
from gentlerl.envs import make_dm_env, make_env


def _rate(fn, steps: int) -> float:
    fn(min(steps, 50))  # warm-up
    start = time.perf_counter()
    fn(steps)
    return steps / (time.perf_counter() - start)


def raw_physics(steps: int) -> float:
    env = make_dm_env("explore", seed=0, time_limit=10**9)
    env.reset()
    physics, n_sub = env.physics, env._n_sub_steps
    low, high = physics.model.actuator_ctrlrange.T
    step = env.task.action_scale * (high - low)
    rng = np.random.default_rng(0)

    def run(n):  # the same delta-position control, with nothing else around it
        for _ in range(n):
            physics.data.ctrl[:] = np.clip(
                physics.data.ctrl + rng.uniform(-1, 1, 20) * step, low, high
            )
            physics.step(n_sub)

    return _rate(run, steps)


def dm_control_env(steps: int) -> float:
    env = make_dm_env("explore", seed=0, time_limit=10**9)
    env.reset()
    rng = np.random.default_rng(0)

    def run(n):
        for _ in range(n):
            env.step(rng.uniform(-1, 1, 20))

    return _rate(run, steps)


def torchrl_step(steps: int, *, with_step_mdp: bool) -> float:
    env = make_env("explore", seed=0, time_limit=10**9)
    td = env.reset()
    torch.manual_seed(0)

    def run(n):
        nonlocal td
        for _ in range(n):
            td.set(keys.ACTION, torch.rand(20) * 2 - 1)
            td = env.step(td)
            if with_step_mdp:
                td = step_mdp(td, keep_other=False)

    return _rate(run, steps)


def torchrl_rollout(steps: int) -> float:
    env = make_env("explore", seed=0, time_limit=10**9)
    return _rate(lambda n: env.rollout(n, break_when_any_done=False), steps)


def parallel(steps: int, workers: int = 2) -> float:
    env = ParallelEnv(workers, _make_explore)
    try:
        return workers * _rate(
            lambda n: env.rollout(n, break_when_any_done=False), steps // workers
        )
    finally:
        env.close()


def _make_explore():
    return make_env("explore", seed=0, time_limit=10**9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--markdown", action="store_true", help="print a RESULTS.md table")
    args = parser.parse_args()
    torch.set_num_threads(1)
    raw = raw_physics(args.steps)
    rows = [
        ("raw physics.step (25 sub-steps)", raw),
        ("dm_control Environment.step", dm_control_env(args.steps)),
        ("TorchRL HandEnv.step", torchrl_step(args.steps, with_step_mdp=False)),
        ("TorchRL HandEnv.step + step_mdp", torchrl_step(args.steps, with_step_mdp=True)),
        ("TorchRL HandEnv.rollout", torchrl_rollout(args.steps)),
        ("ParallelEnv, 2 workers (total)", parallel(args.steps)),
    ]
    if args.markdown:
        print("| what | control steps/s | × raw |\n| --- | ---: | ---: |")
    for name, rate in rows:
        if args.markdown:
            print(f"| {name} | {rate:,.0f} | {rate / raw:.2f} |")
        else:
            print(f"{name:34s} {rate:9.0f} steps/s  {rate / raw:5.2f} x raw")


if __name__ == "__main__":
    main()
