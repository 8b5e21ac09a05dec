"""The prioritised replay's sample + priority update per second, its storage on each device.

    python benchmarks/replay_device.py [--devices cpu cuda] [--capacity 1000000]
        [--filled 100000] [--batch 256] [--min-time 2] [--json F]

The learner's buffer as training builds it (:func:`gentlerl.data.make_replay_buffer`, TorchRL's
``PrioritizedSampler`` logic over :class:`~gentlerl.data.prioritized.FlatPriorityTree`), paper
scale by default (1M slots, batch 256), ``--filled`` transitions of the hand's observation and
action sizes written first. One iteration is what the training loop does per update: ``sample``
then ``update_tensordict_priority`` with new priorities; on a CUDA device the transitions and
trees live on the GPU (``replay.device=learner``) and the batch arrives there. Each row also
checks the sampler: the share of draws landing on the top-priority tenth of the buffer against
that tenth's share of the priority mass (equal up to sampling noise when it samples by priority).
"""

from __future__ import annotations

import argparse
import json
import time

import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.data import make_replay_buffer
from gentlerl.envs.hand import FLAT_SIZE, N_ACTUATORS


def _transitions(n: int) -> TensorDict:
    g = torch.Generator().manual_seed(0)
    obs = torch.randn(n, FLAT_SIZE, generator=g)
    return TensorDict(
        {
            keys.OBSERVATION: obs,
            keys.ACTION: torch.rand(n, N_ACTUATORS, generator=g) * 2 - 1,
            "next": {keys.OBSERVATION: obs, keys.REWARD: torch.randn(n, 1, generator=g)},
        },
        [n],
    )


def time_device(device: str, capacity: int, filled: int, batch: int, min_time: float) -> dict:
    """Iterations/s of sample + priority update, and the sampler's top-tenth check."""
    torch.manual_seed(0)
    start = time.perf_counter()
    rb = make_replay_buffer(capacity, batch, n_steps=None, device=device)
    rb.extend(_transitions(filled))
    priority = torch.linspace(0.01, 10.0, filled, device=device)
    rb.update_priority(torch.arange(filled, device=device), priority)
    setup_s = time.perf_counter() - start

    def step() -> torch.Tensor:
        sample = rb.sample()
        sample.set(keys.PRIORITY, torch.rand(batch, device=sample.device) + 0.5)
        index = sample.get("index")
        rb.update_tensordict_priority(sample)
        return index

    top = filled - filled // 10
    mass = (priority + 1e-8) ** 0.6
    expected = float(mass[top:].sum() / mass.sum())
    drawn = torch.cat([step() for _ in range(5)]).float()  # warm-up, before priorities move
    share = float((drawn >= top).float().mean())
    sync = torch.cuda.synchronize if device.startswith("cuda") else (lambda: None)
    sync()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < min_time:
        step()
        n += 1
    sync()
    rate = n / (time.perf_counter() - t0)
    return {
        "device": device, "per_s": rate, "ms": 1e3 / rate, "setup_s": setup_s,
        "top_tenth_share": share, "top_tenth_mass": expected,
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", nargs="+", default=["cpu", "cuda"])
    parser.add_argument("--capacity", type=int, default=1_000_000)
    parser.add_argument("--filled", type=int, default=100_000)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--min-time", type=float, default=2.0)
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()
    if not 0 < args.filled <= args.capacity or args.batch < 1:
        parser.error(
            f"need 0 < --filled <= --capacity and --batch >= 1, got filled={args.filled}, "
            f"capacity={args.capacity}, batch={args.batch}"
        )
    for device in args.devices:
        if device.startswith("cuda") and not torch.cuda.is_available():
            parser.error(f"--devices {device}: torch {torch.__version__} sees no CUDA device")
    torch.set_num_threads(1)
    print(
        f"replay_device: {args.capacity:,} slots, {args.filled:,} filled, batch {args.batch}, "
        f"torch {torch.__version__}\n"
    )
    print("| storage | sample + update / s | ms | set-up s | draws on the top tenth (mass) |")
    print("| --- | ---: | ---: | ---: | ---: |", flush=True)
    rows = []
    for device in args.devices:
        r = time_device(device, args.capacity, args.filled, args.batch, args.min_time)
        rows.append(r)
        print(
            f"| {device} | {r['per_s']:.0f} | {r['ms']:.2f} | {r['setup_s']:.1f} | "
            f"{r['top_tenth_share']:.3f} ({r['top_tenth_mass']:.3f}) |",
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"torch": torch.__version__, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
