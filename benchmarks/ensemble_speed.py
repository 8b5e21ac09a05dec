"""Batched ensemble vs a python loop of 5 nets: forward + backward, batch 256.

    python benchmarks/ensemble_speed.py [--threads 1] [--markdown]

Both compute the same thing: 5 Gaussian MLPs (63 + 20 -> 3 x 128 ReLU -> mean, variance of 24
outputs), each on its own bootstrap batch of 256, NLL loss, backward. The batched version is
gentlerl's GaussianEnsemble (weights [E, in, out], one baddbmm per layer).
"""

from __future__ import annotations

import argparse
import time

import torch
from torch import nn

from gentlerl.functional import gaussian_nll
from gentlerl.models import GaussianEnsemble

E, B, IN, OUT, H = 5, 256, 83, 24, 128


def _rate(fn, min_time: float = 3.0) -> float:
    for _ in range(10):
        fn()
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < min_time:
        fn()
        n += 1
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    x, y = torch.randn(E, B, IN), torch.randn(E, B, OUT)
    batched = GaussianEnsemble(IN, OUT, E, (H, H, H))
    nets = [
        nn.Sequential(nn.Linear(IN, H), nn.ReLU(), nn.Linear(H, H), nn.ReLU(),
                      nn.Linear(H, H), nn.ReLU(), nn.Linear(H, 2 * OUT))
        for _ in range(E)
    ]  # fmt: skip

    def run_batched() -> None:
        mean, var = batched(x)
        gaussian_nll(y, mean, var).mean().backward()

    def run_loop() -> None:
        total = 0.0
        for e, net in enumerate(nets):
            mean, raw = net(x[e]).split(OUT, -1)
            total = total + gaussian_nll(y[e], mean, nn.functional.softplus(raw) + 1e-4).mean()
        total.backward()

    fast, slow = _rate(run_batched), _rate(run_loop)
    rows = [
        ("batched ensemble (fwd+bwd), calls/s", f"{fast:.0f}"),
        ("python loop of 5 nets (fwd+bwd), calls/s", f"{slow:.0f}"),
        ("speed-up", f"{fast / slow:.2f}x"),
    ]
    header = f"E={E}, batch {B} per member, 3 x {H} hidden, torch threads {args.threads}"
    if args.markdown:
        print(header + "\n\n| what | value |\n| --- | ---: |")
        print("\n".join(f"| {a} | {b} |" for a, b in rows))
    else:
        print(header)
        print("\n".join(f"{a:<45} {b}" for a, b in rows))


if __name__ == "__main__":
    main()
