"""Learner throughput: full D4PG updates/s at paper scale, and fused vs looped critics.

    python benchmarks/learner_speed.py [--threads 2] [--device cpu] [--markdown]

"Full update" = one MultiHeadD4PGLoss update (batch 256, 4 critic heads 400-300, 101 atoms, actor
300-200) + one penalty-ensemble update (5 members x 3 x 128, bootstrap batch 5 x 256), both with
Adam. "Fused vs loop" times forward+backward of the K=4 critics as one FusedCritic against a python
loop over 4 separate nn.Sequential critics with the same architecture. The CPU matmul peak is
estimated with a large float32 matmul on the same threads.
"""

from __future__ import annotations

import argparse
import platform
import time

import torch
from tensordict import TensorDict
from torch import nn

from gentlerl import keys
from gentlerl.models import FusedCritic, PenaltyModel, make_actor, make_critic
from gentlerl.objectives import EnsembleModelLoss, MultiHeadD4PGLoss

OBS, ACT, K, B, ATOMS = 63, 20, 4, 256, 101
REWARD_KEYS = ["reward", "penalty", "penalty_surprise", "dynamics_surprise"]


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _time(fn, device: str, warmup: int = 5, min_time: float = 3.0) -> float:
    """Seconds per call (median-free: total time over as many calls as fit in ``min_time``)."""
    for _ in range(warmup):
        fn()
    _sync(device)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < min_time:
        fn()
        n += 1
    _sync(device)
    return (time.perf_counter() - start) / n


def _batch(device: str) -> TensorDict:
    td = TensorDict(
        {
            keys.OBSERVATION: torch.randn(B, OBS),
            keys.ACTION: torch.rand(B, ACT) * 2 - 1,
            "steps_to_next_obs": torch.full((B,), 5),
            "next": {
                keys.OBSERVATION: torch.randn(B, OBS),
                keys.NSTEP_TERMINATED: torch.zeros(B, 1, dtype=torch.bool),
                **{k: torch.randn(B, 1) for k in REWARD_KEYS},
            },
        },
        [B],
    )
    return td.to(device)


def full_update(device: str) -> float:
    loss = MultiHeadD4PGLoss(
        make_actor(OBS, ACT, (300, 200)),
        make_critic(OBS, ACT, K, (400, 300), ATOMS),
        reward_keys=REWARD_KEYS,
    ).to(device)
    loss.set_keys(terminated=keys.NSTEP_TERMINATED)
    opt_a = torch.optim.Adam(loss.actor_network_params.values(True, True), 1e-4)
    opt_c = torch.optim.Adam(loss.value_network_params.values(True, True), 1e-4)
    model = EnsembleModelLoss(PenaltyModel(OBS, ACT, 5, (128, 128, 128)), name="penalty").to(device)
    opt_m = torch.optim.Adam(model.parameters(), 1e-3)
    batch = _batch(device)
    model_batch = batch.expand(5, B).clone()
    model_batch["next", keys.PENALTY] = torch.randn(5, B, 1, device=device)

    def step() -> None:
        out = model(model_batch)
        opt_m.zero_grad()
        out["loss_penalty"].backward()
        opt_m.step()
        out = loss(batch)
        opt_a.zero_grad()
        opt_c.zero_grad()
        (out["loss_value"] + out["loss_actor"]).backward()
        opt_c.step()
        opt_a.step()

    return 1.0 / _time(step, device)


def _loop_critics(device: str) -> nn.ModuleList:
    def one() -> nn.Sequential:
        return nn.Sequential(
            nn.Linear(OBS + ACT, 400),
            nn.LayerNorm(400),
            nn.Tanh(),
            nn.Linear(400, 300),
            nn.ELU(),
            nn.Linear(300, ATOMS),
        )

    return nn.ModuleList(one() for _ in range(K)).to(device)


def critics(device: str) -> tuple[float, float, float]:
    """(fused calls/s, loop calls/s, fused GFLOP/s) for forward+backward on batch 256."""
    fused = FusedCritic(OBS, ACT, K, (400, 300), ATOMS).to(device)
    loop = _loop_critics(device)
    obs, act = torch.randn(B, OBS, device=device), torch.randn(B, ACT, device=device)
    x = torch.cat([obs, act], -1)

    def run_fused() -> None:
        fused(obs, act).sum().backward()

    def run_loop() -> None:
        torch.stack([c(x) for c in loop], -2).sum().backward()

    t_fused, t_loop = _time(run_fused, device), _time(run_loop, device)
    flops = 3 * 2 * B * K * ((OBS + ACT) * 400 + 400 * 300 + 300 * ATOMS)  # fwd + 2x bwd
    return 1 / t_fused, 1 / t_loop, flops / t_fused / 1e9


def matmul_peak(device: str) -> float:
    a = torch.randn(2048, 2048, device=device)
    t = _time(lambda: a @ a, device, min_time=2.0)
    return 2 * 2048**3 / t / 1e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    ups = full_update(args.device)
    fused, looped, gflops = critics(args.device)
    peak = matmul_peak(args.device)
    name = (
        torch.cuda.get_device_name()
        if args.device.startswith("cuda")
        else platform.processor() or platform.machine()
    )
    rows = [
        ("full update (D4PG 4 heads + penalty ensemble), updates/s", f"{ups:.1f}"),
        ("fused critics fwd+bwd, calls/s", f"{fused:.1f}"),
        ("loop of 4 critics fwd+bwd, calls/s", f"{looped:.1f}"),
        ("fused / loop speed-up", f"{fused / looped:.2f}x"),
        ("fused critics GFLOP/s (share of matmul peak)", f"{gflops:.1f} ({gflops / peak:.0%})"),
        ("matmul peak (2048^2 fp32), GFLOP/s", f"{peak:.1f}"),
    ]
    header = f"device: {args.device} ({name}), torch threads: {args.threads}, batch {B}"
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
