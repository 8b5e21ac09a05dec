"""Which exact fp32 matmul path is fastest for the learner's GEMMs on this CPU (Throughput III).

    python benchmarks/matmul_paths.py [--part gemm|env|critic|update|all] [--rounds 25]
        [--min-time 0.12] [--update-rounds 9] [--update-min-time 1.5]

Every part times its candidates on one torch thread, interleaved (A, B, C, C, B, A, ...), and
prints per candidate the best and median time of a block and its speed against the first row:
the worst and the median of the per-round ratios (> 1: faster). Parts:

- ``gemm``: one ``[384, 256] x [256, 256]`` product (the critic's layer 2, 3 heads x 128 rows) and
  a 2048^2 one, with MKL (``torch.addmm``: what ``baddbmm`` / ``addmm`` run) and with oneDNN (its
  inner product, ``torch.ops.mkldnn._linear_pointwise`` on plain tensors; ``mkldnn_linear`` on a
  ``to_mkldnn()`` input).
- ``env``: MKL's environment knobs (``MKL_ENABLE_INSTRUCTIONS``, ``MKL_DEBUG_CPU_TYPE``,
  ``MKL_CBWR``), one process each, timing the fused critic's forward+backward (``reference``).
- ``critic``: ``FusedCritic`` forward+backward at the recipe's sizes (batch 128, 3 heads 256-256 x
  101 atoms) with its layers as: ``baddbmm`` (the module), the first layer as one
  ``[B, in] x [in, K*h]`` GEMM, per-head MKL products, per-head oneDNN products; then
  ``torch.compile`` of the module. Every variant is checked against the module first (values and
  gradients within 1e-5 relative).
- ``update``: the full update of ``learner_speed.py`` (recipe scale) with the critic's and the
  actor's layers on each path, one process each, and the plain fused critic's forward+backward
  (the issue's reference: its "x first" is the update's cost in critic forward+backwards).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import side_by_side
import torch
from torch import nn

SRC = str(side_by_side.ROOT / "src")

#: oneDNN's inner product on plain fp32 tensors: ``x @ w.T + b`` for ``w`` ``[out, in]``.
_LP = torch.ops.mkldnn._linear_pointwise


def onednn_linear(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    return _LP(x, w, b, "none", [], "")


class OneDNNHeads(torch.autograd.Function):
    """``baddbmm(bias, x, weight)`` for ``[K, B, in] x [K, in, out]``, head by head through oneDNN."""

    @staticmethod
    def forward(ctx, x, weight, bias):
        ctx.save_for_backward(x, weight)
        heads = range(weight.shape[0])
        return torch.stack([onednn_linear(x[k], weight[k].t(), bias[k].view(-1)) for k in heads])

    @staticmethod
    def backward(ctx, grad):
        x, weight = ctx.saved_tensors
        # An expanded gradient (of a .sum()) sends oneDNN to its reference kernel: ~50x slower.
        grad = grad.contiguous()
        heads = range(weight.shape[0])
        gx = gw = gb = None
        if ctx.needs_input_grad[0]:
            gx = torch.stack([onednn_linear(grad[k], weight[k]) for k in heads])
        if ctx.needs_input_grad[1]:
            gw = torch.stack([onednn_linear(x[k].t(), grad[k].t()) for k in heads])
        if ctx.needs_input_grad[2]:
            gb = grad.sum(1, keepdim=True)
        return gx, gw, gb


class MKLHeads(torch.autograd.Function):
    """The same, head by head through MKL's ``addmm`` / ``mm``, written into one output."""

    @staticmethod
    def forward(ctx, x, weight, bias):
        ctx.save_for_backward(x, weight)
        out = x.new_empty(weight.shape[0], x.shape[1], weight.shape[2])
        for k in range(weight.shape[0]):
            torch.addmm(bias[k], x[k], weight[k], out=out[k])
        return out

    @staticmethod
    def backward(ctx, grad):
        x, weight = ctx.saved_tensors
        gx = gw = gb = None
        if ctx.needs_input_grad[0]:
            gx = x.new_empty(x.shape)
            for k in range(weight.shape[0]):
                torch.mm(grad[k], weight[k].t(), out=gx[k])
        if ctx.needs_input_grad[1]:
            gw = torch.empty_like(weight)
            for k in range(weight.shape[0]):
                torch.mm(x[k].t(), grad[k], out=gw[k])
        if ctx.needs_input_grad[2]:
            gb = grad.sum(1, keepdim=True)
        return gx, gw, gb


def critic_forward(critic: nn.Module, obs, act, path: str) -> torch.Tensor:
    """``FusedCritic``'s logits ``[B, K, atoms]`` with its layers on ``path``."""
    x = torch.cat([obs, act], -1)
    heads = critic.num_heads
    first = critic.layers[0]
    if path == "wide":  # the shared input times every head's first layer: one GEMM
        _, n_in, n_out = first.weight.shape
        w = first.weight.transpose(0, 1).reshape(n_in, heads * n_out)
        b = first.bias.transpose(0, 1).reshape(1, heads * n_out)
        h = torch.addmm(b, x, w).view(-1, heads, n_out).transpose(0, 1)
    h_in = x.reshape(1, -1, x.shape[-1]).expand(heads, -1, -1)
    fn = {"onednn": OneDNNHeads.apply, "mkl-heads": MKLHeads.apply}.get(path)

    def linear(layer: nn.Module, h: torch.Tensor) -> torch.Tensor:
        return layer(h) if fn is None else fn(h, layer.weight, layer.bias)

    if path != "wide":
        h = linear(first, h_in)
    h = torch.tanh(critic.norm(h))
    for layer in critic.layers[1:]:
        h = nn.functional.elu(linear(layer, h))
    return linear(critic.head, h).transpose(0, 1)


def interleave(cands: dict[str, Callable[[], object]], rounds: int, min_time: float) -> None:
    """Time each candidate for ``min_time`` per round, order reversed every round; a table."""
    for fn in cands.values():
        for _ in range(3):
            fn()
    times: dict[str, list[float]] = {name: [] for name in cands}
    for r in range(rounds):
        for name in list(cands) if r % 2 == 0 else reversed(list(cands)):
            n, start = 0, time.perf_counter()
            while (elapsed := time.perf_counter() - start) < min_time or n == 0:
                cands[name]()
                n += 1
            times[name].append(elapsed / n)
    _table(times, "us per call", 1e6)


def _table(times: dict[str, list[float]], unit: str, scale: float) -> None:
    base = next(iter(times.values()))
    print(f"\n| candidate | best {unit} | median {unit} | x first: worst round | median round |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, t in times.items():
        ratios = [b / a for a, b in zip(t, base, strict=True)]
        best, med = min(t) * scale, statistics.median(t) * scale
        print(
            f"| {name} | {best:.1f} | {med:.1f} | {min(ratios):.3f} | {statistics.median(ratios):.3f} |"
        )


def part_gemm(args: argparse.Namespace) -> None:
    x, w, b = torch.randn(384, 256), torch.randn(256, 256), torch.randn(256)
    wt, xm, big = w.t().contiguous(), x.to_mkldnn(), torch.randn(2048, 2048)
    print("\n### [384, 256] x [256, 256] (GFLOP/s = 50,330 / us)")
    interleave(
        {
            "MKL addmm": lambda: torch.addmm(b, x, w),
            "oneDNN _linear_pointwise, weight [out, in]": lambda: onednn_linear(x, wt, b),
            "oneDNN _linear_pointwise, weight w.t() (a view)": lambda: onednn_linear(x, w.t(), b),
            "oneDNN mkldnn_linear, to_mkldnn() input": lambda: torch._C._nn.mkldnn_linear(
                xm, wt, b
            ),
        },
        args.rounds,
        args.min_time,
    )
    print("\n### 2048^2 (GFLOP/s = 17,180,000 / us)")
    interleave(
        {"MKL mm": lambda: big @ big, "oneDNN": lambda: onednn_linear(big, big)},
        max(3, args.rounds // 3),
        4 * args.min_time,
    )


#: MKL's knobs, one process each (the first row: none set).
MKL_KNOBS = {
    "default": {},
    "MKL_ENABLE_INSTRUCTIONS=AVX512": {"MKL_ENABLE_INSTRUCTIONS": "AVX512"},
    "MKL_ENABLE_INSTRUCTIONS=AVX2": {"MKL_ENABLE_INSTRUCTIONS": "AVX2"},
    "MKL_DEBUG_CPU_TYPE=5": {"MKL_DEBUG_CPU_TYPE": "5"},
    "MKL_CBWR=AUTO": {"MKL_CBWR": "AUTO"},
    "MKL_CBWR=AVX2": {"MKL_CBWR": "AVX2"},
    "MKL_CBWR=AVX512": {"MKL_CBWR": "AVX512"},
    "MKL_CBWR=COMPATIBLE": {"MKL_CBWR": "COMPATIBLE"},
}


def part_env(args: argparse.Namespace) -> None:
    runs = {
        name: (["--serve=reference", f"--min-time={args.update_min_time / 3}"], SRC)
        for name in MKL_KNOBS
    }
    rates = side_by_side.run_rounds(Path(__file__).resolve(), runs, args.update_rounds, MKL_KNOBS)
    _table({k: [1 / r for r in v] for k, v in rates.items()}, "ms per call", 1e3)


def part_critic(args: argparse.Namespace) -> None:
    from gentlerl.models import FusedCritic

    critic = FusedCritic(63, 20, 3, (256, 256), 101)
    obs, act = torch.randn(128, 63), torch.randn(128, 20, requires_grad=True)
    grad = torch.randn(128, 3, 101)
    inputs = [act, *critic.parameters()]
    compiled = torch.compile(critic)

    def run(path: str) -> Callable[[], tuple[torch.Tensor, ...]]:
        def step() -> tuple[torch.Tensor, ...]:
            if path == "module":
                logits = critic(obs, act)[0]
            elif path == "compiled":
                logits = compiled(obs, act)[0]
            else:
                logits = critic_forward(critic, obs, act, path)
            return (logits, *torch.autograd.grad(logits, inputs, grad))

        return step

    paths = {
        "FusedCritic (baddbmm)": "module",
        "first layer one [B, in] x [in, K*h] addmm": "wide",
        "per-head MKL addmm / mm": "mkl-heads",
        "per-head oneDNN": "onednn",
        "torch.compile(FusedCritic)": "compiled",
    }
    cands = {name: run(path) for name, path in paths.items()}
    expected = cands["FusedCritic (baddbmm)"]()
    for name, fn in cands.items():  # the same values and gradients before any timing
        for got, want in zip(fn(), expected, strict=True):
            torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-5, msg=name)
    print("\n### FusedCritic forward + backward (params and action), batch 128, 3 x 256-256 x 101")
    interleave(cands, args.rounds, 3 * args.min_time)


def part_update(args: argparse.Namespace) -> None:
    runs = {
        "full update, critic baddbmm, actor addmm (main)": ["--serve=update:module"],
        "full update, critic + actor per-head oneDNN": ["--serve=update:onednn"],
        "full update, critic per-head MKL": ["--serve=update:mkl-heads"],
        "full update, critic first layer one GEMM": ["--serve=update:wide"],
        "plain FusedCritic forward + backward (reference)": ["--serve=reference"],
    }
    runs = {k: ([*v, f"--min-time={args.update_min_time}"], SRC) for k, v in runs.items()}
    rates = side_by_side.run_rounds(Path(__file__).resolve(), runs, args.update_rounds)
    _table({k: [1 / r for r in v] for k, v in rates.items()}, "ms per call", 1e3)


def _patch_models(path: str) -> None:
    """Route every ``FusedCritic`` (and, for ``onednn``, every ``nn.Linear``) through ``path``."""
    from gentlerl.models import FusedCritic

    def forward(self, obs, act):  # noqa: ANN001, ANN202
        batch = obs.shape[:-1]
        flat = (obs.reshape(-1, obs.shape[-1]), act.reshape(-1, act.shape[-1]))
        logits = critic_forward(self, *flat, path).reshape(*batch, self.num_heads, -1)
        return logits, self.support.to(logits).expand_as(logits)

    def linear(self, x):  # noqa: ANN001, ANN202  (one "head": weight [1, in, out], a view)
        flat = x.reshape(1, -1, x.shape[-1])
        out = OneDNNHeads.apply(flat, self.weight.t()[None], self.bias[None, None])
        return out.reshape(*x.shape[:-1], -1)

    if path != "module":
        FusedCritic.forward = forward
    if path == "onednn":
        nn.Linear.forward = linear


def serve(args: argparse.Namespace) -> None:
    """A worker: set up, print ``ready``, then one rate (calls/s) per line read on stdin."""
    import learner_speed as ls

    from gentlerl.models import FusedCritic

    scale = ls.make_scale("recipe")
    if args.serve == "reference":
        net = scale.cfg.network
        critic = FusedCritic(ls.OBS, ls.ACT, len(scale.heads), net.critic_hidden, net.num_atoms)
        obs, act = torch.randn(scale.batch, ls.OBS), torch.randn(scale.batch, ls.ACT)

        def step() -> None:  # as learner_speed's "fused critics fwd+bwd" row
            critic(obs, act)[0].sum().backward()
    else:
        _patch_models(args.serve.split(":")[1])
        step = ls.make_full_update(scale, "cpu")
    for _ in range(10):
        step()
    print("ready", flush=True)
    for _ in sys.stdin:
        print(1.0 / ls._time(step, "cpu", args.min_time, warmup=2), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", default="all", choices=["gemm", "env", "critic", "update", "all"])
    parser.add_argument("--rounds", type=int, default=25, help="in-process parts: rounds")
    parser.add_argument("--min-time", type=float, default=0.12, help="in-process: s per block")
    parser.add_argument("--update-rounds", type=int, default=9, help="process parts: rounds")
    parser.add_argument("--update-min-time", type=float, default=1.5, help="s per block")
    parser.add_argument("--serve", help=argparse.SUPPRESS)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    if args.serve:
        return serve(args)
    cpu = torch.backends.cpu.get_cpu_capability()
    print(
        f"torch {torch.__version__}, CPU capability {cpu}, 1 thread, load {os.getloadavg()[0]:.1f}"
    )
    parts = {"gemm": part_gemm, "env": part_env, "critic": part_critic, "update": part_update}
    for name, part in parts.items():
        if args.part in (name, "all"):
            part(args)
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
