"""Batched ensembles vs a python loop of separate nets: forward + backward of the Gaussian NLL.

    python benchmarks/ensemble_speed.py [--threads 1] [--markdown]

Each case computes the same thing both ways: Gaussian MLPs (63 + 20 inputs -> 3 x 128 ReLU ->
mean, variance), each member on its own bootstrap batch, NLL loss, backward. "batched" is gentlerl's
GaussianEnsemble (weights [E, in, out], one baddbmm per layer); "loop" is one nn.Sequential per
member. Cases: one 5-member ensemble at two batch sizes, and the paper's full dynamics model (three
5-member ensembles predicting joint_pos 24, joint_vel 24, touch 15 -> 3 batched calls vs 15 nets).
Timings are the best of interleaved blocks, so every row sees the same background load.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import torch
from torch import nn

from gentlerl.functional import gaussian_nll
from gentlerl.models import GaussianEnsemble

E, IN, H = 5, 63 + 20, 128


def _loop_nets(out_dim: int) -> list[nn.Sequential]:
    return [
        nn.Sequential(nn.Linear(IN, H), nn.ReLU(), nn.Linear(H, H), nn.ReLU(),
                      nn.Linear(H, H), nn.ReLU(), nn.Linear(H, 2 * out_dim))
        for _ in range(E)
    ]  # fmt: skip


def _case(batch: int, out_dims: tuple[int, ...]) -> tuple[Callable[[], None], Callable[[], None]]:
    """(batched, loop) callables for ensembles of E members, one per output size."""
    x = torch.randn(E, batch, IN)
    ys = [torch.randn(E, batch, d) for d in out_dims]
    batched = [GaussianEnsemble(IN, d, E, (H, H, H)) for d in out_dims]
    loops = [_loop_nets(d) for d in out_dims]

    def run_batched() -> None:
        total = 0.0
        for ensemble, y in zip(batched, ys, strict=True):
            mean, var = ensemble(x)
            total = total + gaussian_nll(y, mean, var).mean()
        total.backward()

    def run_loop() -> None:
        total = 0.0
        for nets, y, d in zip(loops, ys, out_dims, strict=True):
            for e, net in enumerate(nets):
                mean, raw = net(x[e]).split(d, -1)
                var = nn.functional.softplus(raw) + 1e-4
                total = total + gaussian_nll(y[e], mean, var).mean()
        total.backward()

    return run_batched, run_loop


def _best_rates(
    fns: list[Callable[[], None]], blocks: int = 5, block_s: float = 0.6
) -> list[float]:
    for fn in fns:  # warm-up
        for _ in range(5):
            fn()
    best = [0.0] * len(fns)
    for _ in range(blocks):
        for i, fn in enumerate(fns):
            n, start = 0, time.perf_counter()
            while time.perf_counter() - start < block_s:
                fn()
                n += 1
            best[i] = max(best[i], n / (time.perf_counter() - start))
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    cases = {
        "1 ensemble (24 outputs), batch 32 / member": _case(32, (24,)),
        "1 ensemble (24 outputs), batch 256 / member": _case(256, (24,)),
        "dynamics model (3 ensembles), batch 256 / member": _case(256, (24, 24, 15)),
    }
    fns = [fn for pair in cases.values() for fn in pair]
    rates = _best_rates(fns)
    header = f"E={E} members, 3 x {H} hidden, fwd+bwd calls/s, torch threads {args.threads}"
    rows = []
    for i, name in enumerate(cases):
        fast, slow = rates[2 * i], rates[2 * i + 1]
        rows.append((name, f"{fast:,.0f}", f"{slow:,.0f}", f"{fast / slow:.2f}x"))
    if args.markdown:
        print(header + "\n\n| case | batched | loop | speed-up |\n| --- | ---: | ---: | ---: |")
        print("\n".join(f"| {' | '.join(row)} |" for row in rows))
    else:
        print(header)
        print("\n".join(f"{a:<50} {b:>8} {c:>8} {d:>8}" for a, b, c, d in rows))


if __name__ == "__main__":
    main()
