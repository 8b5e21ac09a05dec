"""Probe the hand's physics regimes: how hard do naive, random and careful policies hit the block?

For each setting (action scale, finger actuator gain, block gap along the plate's normal) it runs:

- **press**: action +1 on all 20 actuators, ``fragile``, 5 episodes: broken how often, max impact;
- **random**: uniformly random actions in [-1, 1]^20, ``explore`` (no termination, 200 steps):
  the share of episodes that touch anything (any fingertip reading > 0.05 N) or the block, and,
  of those that touch, the share whose max impact exceeds 5 N (the paper's "often exceed 5 N");
- **scripted**: a gradual press on ``fragile``, 5 episodes: the index knuckle (A_FFJ2) target
  moves 0.03 rad per step until its fingertip senses the block, then 0.006 rad per step: success,
  broken, max impact (the task must stay solvable, gently).

Impact is the paper's eq. 1 per fingertip, summed over the three channels; "max impact" is the
episode's largest over fingertips and steps. Run:
``python experiments/regimes.py [--random-episodes 40] [--seed 0]``; prints a markdown table.
"""

from __future__ import annotations

import argparse
import platform
import time
from dataclasses import dataclass

import numpy as np

from gentlerl.envs import make_dm_env

KNUCKLE = 3  # A_FFJ2
APPROACH, PRESS = 0.03, 0.006  # rad per control step of the scripted press
TOUCHED = 0.05  # N: a reading above this counts as touching


@dataclass(frozen=True)
class Setting:
    """One physics regime: ``make_dm_env`` keyword arguments."""

    action_scale: float
    actuator_gain: float
    block_gap: float  # m, along the plate's normal, away from the finger pads

    def kwargs(self) -> dict:
        return {
            "action_scale": self.action_scale,
            "actuator_gain": self.actuator_gain,
            "block_gap": self.block_gap,
        }


def _impact(touch: np.ndarray, previous: np.ndarray) -> float:
    return float(np.clip(touch - previous, 0.0, None).sum(-1).max())


def _episode(env, policy) -> dict:
    """Run one episode of ``policy(step, touch) -> action``; its outcome and max impact."""
    ts = env.reset()
    touch = ts.observation["touch"].copy()
    max_impact, touched, on_block, step = 0.0, False, False, 0
    while not ts.last():
        ts = env.step(policy(step, touch))
        new = ts.observation["touch"].copy()
        max_impact = max(max_impact, _impact(new, touch))
        touched = touched or bool((new > TOUCHED).any())
        on_block = on_block or bool(env.physics.block_contact().any())
        touch, step = new, step + 1
    task = env.task
    return {
        "impact": max_impact,
        "touched": touched,
        "block": on_block,
        "success": task.success,
        "broken": task.broken,
        "steps": step,
    }


def press(setting: Setting, episodes: int, seed: int) -> list[dict]:
    """Action +1 on every actuator until the fragile episode ends."""
    out = []
    for k in range(episodes):
        env = make_dm_env("fragile", seed=seed + k, **setting.kwargs())
        out.append(_episode(env, lambda step, touch: np.ones(20)))
    return out


def random_actions(setting: Setting, episodes: int, seed: int) -> list[dict]:
    """Uniformly random actions for 200 steps of ``explore`` (nothing ends an episode early)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(episodes):
        env = make_dm_env("explore", seed=seed + k, **setting.kwargs())
        out.append(_episode(env, lambda step, touch: rng.uniform(-1.0, 1.0, 20)))
    return out


def scripted(setting: Setting, episodes: int, seed: int) -> list[dict]:
    """The gradual knuckle press described in the module docstring, on ``fragile``."""
    out = []
    for k in range(episodes):
        env = make_dm_env("fragile", seed=seed + k, **setting.kwargs())
        low, high = env.physics.model.actuator_ctrlrange.T
        unit = setting.action_scale * (high - low)
        contact = [False]

        def policy(step, touch, unit=unit, contact=contact):
            contact[0] = contact[0] or bool(touch[0, 0] > TOUCHED)
            action = np.zeros(20)
            action[KNUCKLE] = min(1.0, (PRESS if contact[0] else APPROACH) / unit[KNUCKLE])
            return action

        out.append(_episode(env, policy))
    return out


def _share(rows: list[dict], key: str) -> float:
    return float(np.mean([r[key] for r in rows])) if rows else float("nan")


def probe(setting: Setting, random_episodes: int, seed: int) -> dict:
    """The table row of one setting."""
    p, s = press(setting, 5, seed), scripted(setting, 5, seed)
    r = random_actions(setting, random_episodes, seed)
    touching = [x for x in r if x["touched"]]
    impacts = np.array([x["impact"] for x in touching]) if touching else np.zeros(1)
    return {
        "press_broken": sum(x["broken"] for x in p),
        "press_impact": float(np.median([x["impact"] for x in p])),
        "random_touch": _share(r, "touched"),
        "random_block": _share(r, "block"),
        "random_over5": float(np.mean(impacts > 5.0)) if touching else float("nan"),
        "random_median": float(np.median(impacts)),
        "scripted_success": sum(x["success"] for x in s),
        "scripted_broken": sum(x["broken"] for x in s),
        "scripted_impact": float(max(x["impact"] for x in s)),
        "scripted_steps": float(np.median([x["steps"] for x in s])),
    }


SETTINGS = (
    Setting(0.02, 3.0, 0.0),
    Setting(0.05, 3.0, 0.0),
    Setting(0.07, 3.0, 0.0),
    Setting(0.1, 3.0, 0.0),
    Setting(0.05, 4.0, 0.0),
    Setting(0.05, 5.0, 0.0),
    Setting(0.05, 5.0, 0.01),
    Setting(0.07, 3.0, 0.01),
)

HEADER = (
    "| action_scale | gain | gap (mm) | press broken /5 | press max impact (N) | random touch "
    "| random block | random > 5 N (of touching) | random median max impact (N) "
    "| scripted success /5 | scripted broken /5 | scripted max impact (N) | scripted steps |\n"
    "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--random-episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    start = time.time()
    print(
        f"{platform.node()} {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, seed {args.seed}"
    )
    print(HEADER)
    for s in SETTINGS:
        row = probe(s, args.random_episodes, args.seed)
        print(
            f"| {s.action_scale:g} | {s.actuator_gain:g} | {1000 * s.block_gap:g} "
            f"| {row['press_broken']} | {row['press_impact']:.1f} | {row['random_touch']:.0%} "
            f"| {row['random_block']:.0%} | {row['random_over5']:.0%} | {row['random_median']:.2f} "
            f"| {row['scripted_success']} | {row['scripted_broken']} "
            f"| {row['scripted_impact']:.2f} | {row['scripted_steps']:.0f} |",
            flush=True,
        )
    print(f"{time.time() - start:.0f} s")


if __name__ == "__main__":
    main()
