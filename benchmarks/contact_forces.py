"""Cost of the ``contacts`` force adapter (``gentlerl.envs.contacts.ContactForces``) per env step.

On a random-action trajectory of an external env (default ``dm_control:walker-walk``) it times,
at every state: the contact forces summed per group (``group_forces``: the ``mj_contactForce``
loop and the numpy grouping) and the transform's whole ``_step`` (the reading, the float32 tensor,
the write into the step's tensordict); and end to end the adapted env's ``step`` against the same
env without the adapter (its other transforms kept), best of interleaved blocks (the CPU is shared). Prints microseconds per
step and the contacts per step. Run: ``python benchmarks/contact_forces.py [--env NAME]
[--steps 2000]``.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch
from torchrl.envs import Compose, TransformedEnv

from gentlerl.envs.contacts import ContactForces, geom_groups, group_forces
from gentlerl.envs.external import make_external_env


def _per_state(env: TransformedEnv, transform: ContactForces, steps: int) -> dict[str, float]:
    """Median us of ``group_forces`` and of ``transform._step`` over ``steps`` random states."""
    model, data = transform.handles()
    member = transform._membership(model)
    lookup = geom_groups(member)
    td = env.reset()
    reads, writes, contacts = [], [], []
    for _ in range(steps):
        td = env.rand_step(td)
        nxt = td["next"]
        t0 = time.perf_counter()
        group_forces(model, data, member, lookup=lookup)
        t1 = time.perf_counter()
        transform._step(td, nxt)
        t2 = time.perf_counter()
        reads.append(t1 - t0)
        writes.append(t2 - t1)
        contacts.append(data.ncon)
        td = env.reset() if nxt["done"].any() else nxt.exclude("reward", "done")
    return {
        "group_forces_us": 1e6 * statistics.median(reads),
        "transform_step_us": 1e6 * statistics.median(writes),
        "contacts_per_step": statistics.mean(contacts),
    }


def _end_to_end(name: str, steps: int, repeats: int = 5) -> dict[str, float]:
    """us per ``rand_step`` of the adapted env and of the same env without ``ContactForces``
    (its other transforms kept), the best of ``repeats`` interleaved blocks each."""
    adapted = make_external_env(name, seed=0)
    others = [t.clone() for t in adapted.transform if not isinstance(t, ContactForces)]
    bare = TransformedEnv(adapted.base_env, Compose(*others))
    best = {"with_adapter_us": float("inf"), "without_us": float("inf")}
    block = max(1, steps // repeats)
    for _ in range(repeats):
        for key, env in (("with_adapter_us", adapted), ("without_us", bare)):
            td = env.reset()
            t0 = time.perf_counter()
            for _ in range(block):
                td = env.rand_step(td)["next"]
                if td["done"].any():
                    td = env.reset()
            best[key] = min(best[key], 1e6 * (time.perf_counter() - t0) / block)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="dm_control:walker-walk")
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args()
    torch.manual_seed(0)
    env = make_external_env(args.env, seed=0)
    transform = next(t for t in env.transform if isinstance(t, ContactForces))
    row = {**_per_state(env, transform, args.steps), **_end_to_end(args.env, args.steps)}
    print(f"{args.env}: sites {transform.sites}")
    for key, value in row.items():
        print(f"  {key:<20} {value:8.1f}")


if __name__ == "__main__":
    main()
