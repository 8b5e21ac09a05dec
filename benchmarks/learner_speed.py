"""Learner throughput: full D4PG updates/s at a run's scale, and fused vs looped critics.

    python benchmarks/learner_speed.py [--scale paper|recipe] [--threads 2] [--device cpu]
        [--min-time 3] [--compile] [--markdown]
    python benchmarks/learner_speed.py --compare REV [--rounds 5] [--scale ...] [--threads 1]

Sizes come from the training config (the presets of ``gentlerl.training.make_config``): ``--scale paper`` is the
``paper`` preset (batch 256, critics 400-300, actor 300-200, 101 atoms, penalty ensemble 5 x 3 x
128 on a bootstrap batch of 5 x 256) with four critic heads (every reward component the paper
learns from); ``--scale recipe`` is the default recipe (``cpu`` preset, default variant: batch
128, critics and actor 256-256, one head per reward component of the variant, penalty ensemble
5 x 3 x 128 on 5 x 64). Observation 63 and action 20 are the hand env's sizes.

"Full update" = one ``Learner.update`` (the multi-head D4PG loss, one grouped Adam step, the
target copy when due) + one penalty-ensemble update (Adam, its target copy when due): the compute
of one step of the training loop, without replay sampling and priority writes. "+ host reads"
also reads every loss output with ``.item()`` as the training loop logs them (on a GPU: one wait
for the device per update). "Fused vs loop" times forward+backward of the critics as one ``FusedCritic`` against a
python loop over separate ``nn.Sequential`` critics of the same architecture. The matmul peak is
a 2048^2 float32 matmul on the same threads / device. ``--compile`` times the update with
``learner.compile`` on.

``--compare REV`` times the full update side by side in one run: the code at git revision ``REV``
(``git archive``, eager, the ensemble's Adam unfused as in ``IntrinsicRewards`` before 77fb784),
this tree eager and this tree compiled. Each runs in its own process, set up and warmed up
(compiled) first; then ``--rounds`` rounds give each process one ``--min-time`` block in turn, so
all three see the same machine load (``side_by_side.py``); a ratio is the median of the
per-round ratios to ``REV``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import side_by_side
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.objectives import HardUpdate

from gentlerl import keys
from gentlerl.agent.learner import Learner
from gentlerl.models import FusedCritic, PenaltyModel, make_actor, make_critic
from gentlerl.models.actor import paper_trunk
from gentlerl.objectives import EnsembleModelLoss, MultiHeadD4PGLoss
from gentlerl.training.config import TrainConfig, preset_config

OBS, ACT = 63, 20
#: The paper scale's heads: all four reward components of the paper's variants.
PAPER_HEADS = ("reward", "penalty", "penalty_surprise", "dynamics_surprise")


@dataclass(frozen=True)
class Scale:
    """What one update processes: the config's sizes and critic heads."""

    cfg: TrainConfig
    heads: tuple[str, ...]

    @property
    def batch(self) -> int:
        return self.cfg.replay.batch_size


def make_scale(name: str) -> Scale:
    """``paper``: the paper preset with :data:`PAPER_HEADS`; ``recipe``: the default recipe."""
    if name == "paper":
        return Scale(preset_config("paper"), PAPER_HEADS)
    if name == "recipe":
        cfg = preset_config("cpu")
        return Scale(cfg, tuple(cfg.reward_keys))
    raise ValueError(f"unknown scale {name!r}; expected 'paper' or 'recipe'")


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _time(fn, device: str, min_time: float, warmup: int = 10) -> float:
    """Seconds per call: total time over as many calls as fit in ``min_time``, after warm-up."""
    for _ in range(warmup):
        fn()
    _sync(device)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < min_time:
        fn()
        n += 1
    _sync(device)
    return (time.perf_counter() - start) / n


def _batch(scale: Scale, device: str) -> TensorDict:
    b = scale.batch
    td = TensorDict(
        {
            keys.OBSERVATION: torch.randn(b, OBS),
            keys.ACTION: torch.rand(b, ACT) * 2 - 1,
            "steps_to_next_obs": torch.full((b,), scale.cfg.replay.n_steps),
            "next": {
                keys.OBSERVATION: torch.randn(b, OBS),
                keys.NSTEP_TERMINATED: torch.zeros(b, 1, dtype=torch.bool),
                **{k: torch.randn(b, 1) for k in scale.heads},
            },
        },
        [b],
    )
    return td.to(device)


def make_loss(scale: Scale) -> MultiHeadD4PGLoss:
    """The D4PG loss of ``scale`` (its actor, critic heads and discount), on the CPU."""
    net, lrn = scale.cfg.network, scale.cfg.learner
    loss = MultiHeadD4PGLoss(
        make_actor(OBS, ACT, net.actor_hidden),
        make_critic(OBS, ACT, len(scale.heads), net.critic_hidden, net.num_atoms),
        reward_keys=list(scale.heads),
    )
    loss.make_value_estimator(gamma=lrn.gamma)
    loss.set_keys(terminated=keys.NSTEP_TERMINATED)
    return loss


def _learner(scale: Scale, device: str, compile: bool = False) -> Learner:
    lrn, loss = scale.cfg.learner, make_loss(scale)
    # Moved before Learner builds its optimiser, so Adam holds the device's parameters.
    options = {"compile": True} if compile else {}  # as a revision without the option is called
    return Learner(
        loss.to(device),
        lr_actor=lrn.lr_actor,
        lr_critic=lrn.lr_critic,
        target_update_period=lrn.target_update_period,
        **options,
    )


def make_full_update(
    scale: Scale, device: str, *, compile: bool = False, fused_model_adam: bool = True
) -> Callable[[], tuple[torch.Tensor, TensorDict]]:
    """One learner update and one penalty-ensemble update (its Adam fused as ``IntrinsicRewards``)."""
    g = scale.cfg.gentleness
    learner = _learner(scale, device, compile)
    model = PenaltyModel(OBS, ACT, g.ensemble_size, (g.model_hidden,) * 3)
    model_loss = EnsembleModelLoss(model, name="penalty").to(device)
    opt_m = torch.optim.Adam(model_loss.parameters(), g.lr_model, fused=fused_model_adam or None)
    model_target = HardUpdate(model_loss, value_network_update_interval=g.penalty_target_period - 1)
    batch = _batch(scale, device)
    model_batch = _batch(scale, device)[: g.model_batch_size]
    model_batch = model_batch.expand(g.ensemble_size, *model_batch.shape).clone()
    model_batch["next", keys.PENALTY] = torch.randn(*model_batch.shape, 1, device=device)

    def step() -> tuple[torch.Tensor, TensorDict]:
        model_out = model_loss(model_batch)["loss_penalty"]
        opt_m.zero_grad()
        model_out.backward()
        opt_m.step()
        model_target.step()
        return model_out, learner.update(batch)

    return step


def full_update(scale: Scale, device: str, min_time: float, compile: bool) -> tuple[float, float]:
    """(updates/s, updates/s with the loop's ``.item()`` reads of every loss output)."""
    step = make_full_update(scale, device, compile=compile)

    def step_and_read() -> None:
        model_out, out = step()
        [v.item() for v in (model_out, *out.values())]

    return 1.0 / _time(step, device, min_time), 1.0 / _time(step_and_read, device, min_time)


def serve(args: argparse.Namespace) -> None:
    """A ``--compare`` worker: warm up, print ``ready``, then time one block per stdin line."""
    step = make_full_update(
        make_scale(args.scale), args.device, compile=args.compile, fused_model_adam=not args.rev
    )
    for _ in range(10):
        step()
    print("ready", flush=True)
    for _ in sys.stdin:
        print(1.0 / _time(step, args.device, args.min_time, warmup=2), flush=True)


def compare(args: argparse.Namespace) -> None:
    """Before (``--compare REV``) vs this tree, eager and compiled, in alternating rounds."""
    common = ["--serve", f"--scale={args.scale}", f"--threads={args.threads}"]
    common += [f"--device={args.device}", f"--min-time={args.min_time}"]
    here = str(side_by_side.ROOT / "src")
    with side_by_side.revision_src(args.compare) as old:
        runs = {
            f"before ({args.compare}), eager": ([*common, f"--serve-rev={args.compare}"], old),
            "after, eager": (common, here),
            "after, learner.compile": ([*common, "--compile"], here),
        }
        rates = side_by_side.run_rounds(Path(__file__).resolve(), runs, args.rounds)
    print(f"\n{args.rounds} rounds of {args.min_time} s, load average {os.getloadavg()[0]:.1f}")
    side_by_side.print_table(rates, "full update", "updates/s")


def _loop_critics(scale: Scale, device: str) -> nn.ModuleList:
    net = scale.cfg.network

    def one() -> nn.Sequential:
        trunk = paper_trunk(OBS + ACT, net.critic_hidden)
        return nn.Sequential(*trunk, nn.Linear(net.critic_hidden[-1], net.num_atoms))

    return nn.ModuleList(one() for _ in scale.heads).to(device)


def critics(scale: Scale, device: str, min_time: float) -> tuple[float, float, float]:
    """(fused calls/s, loop calls/s, fused GFLOP/s) for forward+backward on one batch."""
    net, k, b = scale.cfg.network, len(scale.heads), scale.batch
    fused = FusedCritic(OBS, ACT, k, net.critic_hidden, net.num_atoms).to(device)
    loop = _loop_critics(scale, device)
    obs, act = torch.randn(b, OBS, device=device), torch.randn(b, ACT, device=device)
    x = torch.cat([obs, act], -1)

    def run_fused() -> None:
        fused(obs, act)[0].sum().backward()

    def run_loop() -> None:
        torch.stack([c(x) for c in loop], -2).sum().backward()

    t_fused, t_loop = _time(run_fused, device, min_time), _time(run_loop, device, min_time)
    widths = [OBS + ACT, *net.critic_hidden, net.num_atoms]
    macs = sum(i * o for i, o in zip(widths, widths[1:], strict=False))
    flops = 3 * 2 * b * k * macs  # forward + 2x backward
    return 1 / t_fused, 1 / t_loop, flops / t_fused / 1e9


def matmul_peak(device: str, min_time: float) -> float:
    a = torch.randn(2048, 2048, device=device)
    return 2 * 2048**3 / _time(lambda: a @ a, device, min_time) / 1e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", default="paper", choices=["paper", "recipe"])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--min-time", type=float, default=3.0, help="seconds timed per row")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--compile", action="store_true", help="learner.compile on")
    parser.add_argument("--compare", metavar="REV", help="before (REV) vs after, side by side")
    parser.add_argument("--rounds", type=int, default=5, help="--compare: rounds of blocks")
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--serve-rev", dest="rev", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    if args.serve:
        return serve(args)
    if args.compare:
        return compare(args)
    scale, t = make_scale(args.scale), args.min_time
    ups, ups_read = full_update(scale, args.device, t, args.compile)
    fused, looped, gflops = critics(scale, args.device, t)
    peak = matmul_peak(args.device, t)
    name = (
        torch.cuda.get_device_name()
        if args.device.startswith("cuda")
        else platform.processor() or platform.machine()
    )
    net, k = scale.cfg.network, len(scale.heads)
    rows = [
        ("full update (D4PG + penalty ensemble), updates/s", f"{ups:.1f}"),
        ("full update, ms", f"{1e3 / ups:.2f}"),
        ("full update + host reads (.item() of each loss), updates/s", f"{ups_read:.1f}"),
        ("fused critics fwd+bwd, calls/s", f"{fused:.1f}"),
        (f"loop of {k} critics fwd+bwd, calls/s", f"{looped:.1f}"),
        ("fused / loop speed-up", f"{fused / looped:.2f}x"),
        ("fused critics GFLOP/s (share of matmul peak)", f"{gflops:.1f} ({gflops / peak:.0%})"),
        ("matmul peak (2048^2 fp32), GFLOP/s", f"{peak:.1f}"),
    ]
    header = (
        f"scale {args.scale}: batch {scale.batch}, {k} heads {'-'.join(map(str, net.critic_hidden))}"
        f" x {net.num_atoms} atoms, actor {'-'.join(map(str, net.actor_hidden))}; device: "
        f"{args.device} ({name}), torch {torch.__version__}, threads: {args.threads}, "
        f"learner.compile: {args.compile}"
    )
    if args.markdown:
        print(header + "\n\n| what | value |\n| --- | ---: |")
        for what, value in rows:
            print(f"| {what} | {value} |")
    else:
        print(header)
        for what, value in rows:
            print(f"{what:<60} {value}")


if __name__ == "__main__":
    main()
