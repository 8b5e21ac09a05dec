"""Learner updates/s by launch mode (eager, compile, CUDA graph, both) and by seeds per process.

    python benchmarks/learner_graphs.py [--device cuda] [--scale paper] [--seeds 1 5] [--models]
        [--modes eager cudagraphs compile+cudagraphs] [--min-time 2] [--threads 1] [--json F]

One row per (mode, seeds): a D4PG update of ``S`` seeds is one :class:`Learner` step on a
``[S, B]`` batch; with ``--models`` a second row per seed count adds the penalty ensemble's step
through the same mode (one :class:`ModelStep` on ``[S, E, B]``), the loop's two updates, each with
the one host
read of its loss the training loop makes. ``updates/s`` counts steps, ``seed-updates/s``
steps x S; the last column is the seed-batched rate per step over the one-seed rate of the same
mode (the goal on a GPU: >= 0.8 at 5 seeds). Modes: ``eager``; ``compile`` (``learner.compile``:
``torch.compile`` of the losses); ``cudagraphs`` (the whole step, Adam included, replayed as one
CUDA graph with ``tensordict.nn.CudaGraphModule``); ``compile+cudagraphs``. Graph modes are CUDA
only and skipped elsewhere. Sizes as ``learner_speed.py --scale`` (paper: batch 256, 4 heads
400-300 x 101 atoms, actor 300-200). Each row: warm-up (compilation and capture) outside the
timing, then as many updates as fit in ``--min-time`` s, synchronised at both ends.
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import torch
from learner_speed import ACT, OBS, Scale, _batch, _time, make_loss, make_scale

from gentlerl import keys
from gentlerl.agent.learner import Learner
from gentlerl.models import PenaltyModel
from gentlerl.objectives import EnsembleModelLoss, MultiHeadD4PGLoss
from gentlerl.rewards.model_step import ModelStep

MODES = ("eager", "compile", "cudagraphs", "compile+cudagraphs")


def _loss(scale: Scale, seed: int, device: str) -> MultiHeadD4PGLoss:
    torch.manual_seed(seed)
    return make_loss(scale).to(device)


def make_update(scale: Scale, seeds: int, mode: str, device: str):
    """``update()``: one learner step of ``seeds`` seeds in ``mode`` on a fixed batch."""
    lrn = scale.cfg.learner
    options = dict(
        lr_actor=lrn.lr_actor,
        lr_critic=lrn.lr_critic,
        target_update_period=lrn.target_update_period,
        compile="compile" in mode,
        cudagraphs="cudagraphs" in mode,
    )
    learner = Learner([_loss(scale, s, device) for s in range(seeds)], **options)
    batch = torch.stack([_batch(scale, device) for _ in range(seeds)])
    return lambda: learner.update(batch)


def _model_batch(scale: Scale, device: str):
    g = scale.cfg.gentleness
    batch = _batch(scale, device)[: g.model_batch_size]
    batch = batch.expand(g.ensemble_size, *batch.shape).clone()
    batch["next", keys.PENALTY] = torch.randn(*batch.shape, 1, device=device)
    return batch


def make_model_update(scale: Scale, seeds: int, mode: str, device: str):
    """``update()``: one penalty-ensemble step of ``seeds`` seeds through ``mode`` (one
    ``ModelStep``), with the read of its loss the loop makes."""
    g = scale.cfg.gentleness
    losses = [
        EnsembleModelLoss(
            PenaltyModel(OBS, ACT, g.ensemble_size, (g.model_hidden,) * 3, seed=s), name="penalty"
        ).to(device)
        for s in range(seeds)
    ]
    options = {"compile": "compile" in mode, "cudagraphs": "cudagraphs" in mode}
    batched = ModelStep(losses, g.lr_model, **options)
    batch = torch.stack([_model_batch(scale, device) for _ in range(seeds)])
    return lambda: batched(batch).tolist()


def time_row(
    scale: Scale, seeds: int, mode: str, device: str, min_time: float, models: bool = False
) -> dict:
    start = time.perf_counter()
    learner = make_update(scale, seeds, mode, device)
    update = learner
    if models:
        model = make_model_update(scale, seeds, mode, device)
        update = lambda: (model(), learner())  # noqa: E731 - the loop's two updates
    warm = 15 if "compile" in mode or "cudagraphs" in mode else 5
    for _ in range(warm):
        update()
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    setup_s = time.perf_counter() - start
    rate = 1.0 / _time(update, device, min_time, warmup=2)
    return {
        "mode": mode, "seeds": seeds, "models": models, "updates_per_s": rate, "setup_s": setup_s
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--scale", default="paper", choices=["paper", "recipe"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 5])
    parser.add_argument(
        "--models", action="store_true", help="also each row with the penalty ensemble's step"
    )
    parser.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    parser.add_argument("--min-time", type=float, default=2.0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()
    if any(s < 1 for s in args.seeds):
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    cuda = args.device.startswith("cuda")
    if cuda and not torch.cuda.is_available():
        parser.error(f"--device {args.device}: torch {torch.__version__} sees no CUDA device")
    torch.set_num_threads(args.threads)
    scale = make_scale(args.scale)
    modes = [m for m in args.modes if cuda or "cudagraphs" not in m]
    name = torch.cuda.get_device_name() if cuda else platform.processor() or platform.machine()
    net = scale.cfg.network
    print(
        f"learner_graphs: scale {args.scale} (batch {scale.batch}, {len(scale.heads)} heads "
        f"{'-'.join(map(str, net.critic_hidden))} x {net.num_atoms}, actor "
        f"{'-'.join(map(str, net.actor_hidden))}), {args.device} ({name}), torch "
        f"{torch.__version__}, {args.threads} thread(s)",
        flush=True,
    )
    print("\n| mode | seeds | updates/s | seed-updates/s | ms/update | vs 1 seed | setup s |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |", flush=True)
    rows, one = [], {}
    kinds = [(s, m) for m in (False, True)[: 1 + args.models] for s in sorted(args.seeds)]
    for mode in modes:
        for seeds, models in sorted(kinds, key=lambda k: (k[1], k[0] != 1, k[0])):
            try:  # 1 seed first in each kind: the ratio's denominator
                row = time_row(scale, seeds, mode, args.device, args.min_time, models)
            except Exception as err:  # one failing mode must not cost the others' numbers
                error = f"{type(err).__name__}: {err}"[:300]
                row = {"mode": mode, "seeds": seeds, "models": models, "error": error}
            rows.append(row)
            if seeds == 1 and "error" not in row:
                one[mode, models] = row["updates_per_s"]
            print(_markdown_row(row, one.get((mode, models))), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"device": name, "torch": torch.__version__, "rows": rows}, f, indent=1)


def _markdown_row(r: dict, one: float | None) -> str:
    seeds = f"{r['seeds']}, + penalty ensemble" if r["models"] else r["seeds"]
    if "error" in r:
        return f"| {r['mode']} | {seeds} | failed: {r['error'][:120]} | | | | |"
    ups = r["updates_per_s"]
    ratio = f"{ups / one:.2f}" if one else "-"
    return (
        f"| {r['mode']} | {seeds} | {ups:.1f} | {ups * r['seeds']:.1f} | {1e3 / ups:.2f} "
        f"| {ratio} | {r['setup_s']:.0f} |"
    )


if __name__ == "__main__":
    main()
