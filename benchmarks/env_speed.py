"""Hand env speed: TorchRL ``HandEnv`` control steps/s vs raw ``physics.step`` of the same model.

Each control step is ``n_sub_steps`` = 25 MuJoCo steps of 2 ms (50 ms, 20 Hz). Rows: raw physics
(the same 25 sub-steps and random delta-position control, nothing else), the dm_control
environment, the TorchRL env (``env.step`` feeding each step's ``"next"`` back in; and with
``step_mdp``), its ``rollout``, the batched env (``make_env(num_envs=N)``, total frames/s over its
hands), TorchRL ``Collector`` s as training runs them (200-frame batches; a random policy, or the
actor with exploration noise; 1, 4 or 8 hands) and a 2-worker ``ParallelEnv`` (total). The ``explore`` task is used so that no episode
ends early. It also measures how often uniformly random actions touch the block, succeed or break
it. Run: ``python benchmarks/env_speed.py [--steps 3000] [--episodes 100] [--markdown]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
import torch
from torchrl.collectors import Collector
from torchrl.envs import ParallelEnv
from torchrl.envs.utils import step_mdp

from gentlerl import keys
from gentlerl.envs import make_dm_env, make_env
from gentlerl.envs.hand import FLAT_SIZE, N_ACTUATORS
from gentlerl.models import make_actor, make_exploration_policy

#: Frames per collector batch in the collector rows (the training recipe's).
BATCH = 200


def _rates(runs: dict[str, tuple[Callable[[int], None], int]], steps: int, repeats: int = 5):
    """Control steps/s of each ``run(n)`` (``factor`` env steps per ``n``), best of ``repeats``
    interleaved blocks: the CPU is shared, so every contender sees the same background load and
    the least disturbed block counts, as with ``timeit``."""
    block = max(1, steps // repeats)
    best = dict.fromkeys(runs, 0.0)
    for run, _ in runs.values():
        run(50)  # warm-up
    for _ in range(repeats):
        for name, (run, factor) in runs.items():
            start = time.perf_counter()
            run(block // factor)
            best[name] = max(best[name], block // factor * factor / (time.perf_counter() - start))
    return best


def random_policy_outcomes(task: str, episodes: int) -> dict[str, float]:
    """Fractions of uniformly random episodes that touch the block / succeed / break it."""
    rng = np.random.default_rng(0)
    counts = {"contact": 0, "success": 0, "broken": 0}
    for episode in range(episodes):
        env = make_dm_env(task, seed=episode)
        ts, contact = env.reset(), False
        while not ts.last():
            ts = env.step(rng.uniform(-1, 1, 20))
            contact = contact or bool(env.physics.block_contact().any())
        counts["contact"] += contact
        counts["success"] += env.task.success
        counts["broken"] += env.task.broken
    return {key: value / episodes for key, value in counts.items()}


def raw_physics() -> Callable[[int], None]:
    """The same 25 sub-steps and delta-position control, with nothing else around them."""
    env = make_dm_env("explore", seed=0, time_limit=10**9)
    env.reset()
    physics, n_sub = env.physics, env.n_sub_steps
    low, high = physics.model.actuator_ctrlrange.T
    step = env.task.action_scale * (high - low)
    rng = np.random.default_rng(0)

    def run(n):
        for _ in range(n):
            ctrl = physics.data.ctrl + rng.uniform(-1, 1, 20) * step
            physics.data.ctrl[:] = np.clip(ctrl, low, high)
            physics.step(n_sub)

    return run


def dm_control_env() -> Callable[[int], None]:
    env = make_dm_env("explore", seed=0, time_limit=10**9)
    env.reset()
    rng = np.random.default_rng(0)

    def run(n):
        for _ in range(n):
            env.step(rng.uniform(-1, 1, 20))

    return run


def torchrl_step(*, with_step_mdp: bool) -> Callable[[int], None]:
    """``env.step`` as a loop over it uses the env: the next input is the last output's
    ``"next"`` entry (no ``"next"`` left in the input to merge), or ``step_mdp`` of it."""
    env = make_env("explore", seed=0, time_limit=10**9)
    td = env.reset()
    rng = np.random.default_rng(0)  # the same actions as above

    def run(n):
        nonlocal td
        for _ in range(n):
            td.set(keys.ACTION, torch.from_numpy(rng.uniform(-1, 1, 20)).float())
            td = env.step(td)
            td = step_mdp(td, keep_other=False) if with_step_mdp else td.get("next")

    return run


def torchrl_rollout() -> Callable[[int], None]:
    env = make_env("explore", seed=0, time_limit=10**9)
    return lambda n: env.rollout(n, break_when_any_done=False)


def batched_rollout(num_envs: int, num_threads: int) -> Callable[[int], None]:
    env = make_env("explore", seed=0, time_limit=10**9, num_envs=num_envs, num_threads=num_threads)
    return lambda n: env.rollout(n, break_when_any_done=False)


def collector(num_envs: int, *, actor: bool) -> Callable[[int], None]:
    """A TorchRL ``Collector`` as training uses it (``run(n)`` pulls ``n`` batches of ``BATCH``
    frames): a random policy (the ``init_random_frames`` phase) or the paper-size actor with
    Gaussian exploration noise; ``num_envs`` hands per env step on one thread."""

    def make():
        return make_env("explore", seed=0, time_limit=10**9, num_envs=num_envs, num_threads=1)

    policy = None
    if actor:
        net = make_actor(FLAT_SIZE, N_ACTUATORS)
        policy = make_exploration_policy(net, 0.3, action_dim=N_ACTUATORS)
    batches = iter(
        Collector(
            make if num_envs > 1 else _make_explore,
            policy,
            frames_per_batch=BATCH,
            total_frames=-1,
            init_random_frames=0 if actor else 10**12,
            auto_register_policy_transforms=False,
            device="cpu",  # as training's collectors (no per-step casts)
        )
    )

    def run(n):
        for _ in range(n):
            next(batches)

    return run


def _make_explore():
    return make_env("explore", seed=0, time_limit=10**9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--episodes", type=int, default=100, help="random-policy episodes")
    parser.add_argument("--markdown", action="store_true", help="print a RESULTS.md table")
    args = parser.parse_args()
    torch.set_num_threads(1)
    workers = 2
    parallel = ParallelEnv(workers, _make_explore)
    runs = {
        "raw physics.step (25 sub-steps)": (raw_physics(), 1),
        "dm_control Environment.step": (dm_control_env(), 1),
        "TorchRL HandEnv.step": (torchrl_step(with_step_mdp=False), 1),
        "TorchRL HandEnv.step + step_mdp": (torchrl_step(with_step_mdp=True), 1),
        "TorchRL HandEnv.rollout": (torchrl_rollout(), 1),
        "BatchedHandEnv.rollout, 4 hands, 1 thread (total)": (batched_rollout(4, 1), 4),
        "BatchedHandEnv.rollout, 4 hands, 2 threads (total)": (batched_rollout(4, 2), 4),
        "BatchedHandEnv.rollout, 8 hands, 2 threads (total)": (batched_rollout(8, 2), 8),
        "Collector, 1 hand, random policy": (collector(1, actor=False), BATCH),
        "Collector, 1 hand, actor + noise": (collector(1, actor=True), BATCH),
        "Collector, 4 hands, 1 thread, actor + noise": (collector(4, actor=True), BATCH),
        "Collector, 8 hands, 1 thread, actor + noise": (collector(8, actor=True), BATCH),
        f"ParallelEnv, {workers} workers (total)": (
            lambda n: parallel.rollout(n, break_when_any_done=False),
            workers,
        ),
    }
    try:
        rates = _rates(runs, args.steps)
    finally:
        parallel.close()
    raw = rates["raw physics.step (25 sub-steps)"]
    rows = list(rates.items())
    if args.markdown:
        print("| what | control steps/s | × raw |\n| --- | ---: | ---: |")
    for name, rate in rows:
        if args.markdown:
            print(f"| {name} | {rate:,.0f} | {rate / raw:.2f} |")
        else:
            print(f"{name:34s} {rate:9.0f} steps/s  {rate / raw:5.2f} x raw")
    if args.episodes:
        print(f"\nuniformly random actions, {args.episodes} episodes of <= 200 steps:")
        for task in ("touch", "fragile"):
            print(task, random_policy_outcomes(task, args.episodes))


if __name__ == "__main__":
    main()
