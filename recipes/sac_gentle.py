"""TorchRL's SAC recipe on the Shadow Hand, with gentleness added through gentlerl's public API.

``python recipes/sac_gentle.py task=fragile variant=r+rf+rsp seed=0`` (``key=value`` overrides of
:class:`SACConfig`; ``--help`` lists them). The shape is TorchRL's ``sota-implementations/sac``
(``make_env``, ``make_sac_agent``, ``make_loss_module``, one loop); the gentleness part is the
lines marked ``# gentlerl``: the variant's rewards from the env's specs, their sum into the one
``reward`` SAC reads, the replay buffer scoring r^sp again at sampling, one model update
per SAC update, and with ``multiplier=pid`` the penalty's weight in the sum steered toward
``tolerance`` by the collected episodes, or by a few noise-free ones per PID step
(``multiplier_episodes``; Method III). ``variant=r`` runs plain SAC on the task reward (the components are still
logged, ``r`` sums the task reward alone).

Writes ``run_dir/actor.pt`` (the final actor's state dict) and ``run_dir/final_eval.json``: the final actor's deterministic episodes on a held-out seed,
as ``gentlerl evaluate --episodes 20 --seed 0`` measures a D4PG run (success, broken rate,
median / p90 max impact in N), and ``run_dir/evals.csv``, the in-loop evaluations.
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
from omegaconf import OmegaConf
from tensordict import TensorDictBase
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import RewardSum, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, SoftUpdate
from tqdm import tqdm

from gentlerl.config import GentlenessConfig, Range, check_group
from gentlerl.envs import TASKS, make_env
from gentlerl.rewards import VARIANTS, ImpactMultiplier, IntrinsicRewards, SumRewards
from gentlerl.training import EVAL_SEED_OFFSET, actor_episodes, evaluate_actor

#: The held-out seed of the final evaluation (``gentlerl evaluate --seed 0``).
FINAL_EVAL_SEED = 0


@dataclass
class SACConfig:
    """The recipe's settings; the defaults are the D4PG grid's CPU budget (30k frames)."""

    task: str = "touch"
    variant: str = "r+rf+rsp"  # r: SAC on the task reward; else a gentlerl variant, summed
    seed: int = 0
    run_dir: str | None = None  # default runs/sac/<task>/<variant>/seed<seed>
    total_frames: int = 30_000
    init_random_frames: int = 5_000
    frames_per_batch: int = 200
    utd_ratio: float = 0.25  # SAC (and model) updates per env step, as the D4PG grid
    batch_size: int = 256
    buffer_size: int = 200_000
    hidden: list[int] = field(default_factory=lambda: [256, 256])
    lr: float = 3e-4
    gamma: float = 0.99
    polyak: float = 0.995
    alpha_init: float = 1.0
    lam_prime: list[float] = field(default_factory=lambda: [2.0, 2.0])  # fragile: [2, 1.5]
    reward_delay: int = 1_000  # model updates, as the D4PG grid's cpu scale
    # Method III (docs/log/GENTLEBENCH.md): the impact one step may deal (N), and the penalty's
    # weight steered toward it by a PID multiplier (pid; its period in env steps, its cap, the
    # weight at mu = 0, and the noise-free episodes per PID step: 0 steers on the collected ones)
    tolerance: float | None = None
    multiplier: str = "none"
    multiplier_period: int | None = None
    multiplier_integral_max: float | None = None
    multiplier_base: float = 1.0
    multiplier_episodes: int = 0
    eval_every_frames: int = 5_000
    eval_episodes: int = 5
    final_eval_episodes: int = 20
    num_threads: int = 1  # torch threads: one run per core, as gentlerl's runs


#: Each number's range, written as ``gentlerl train`` writes its own (``gentlerl.config.Range``;
#: the seed's is gentlerl's: numpy seeds below 2**32 take the seed plus offsets).
BOUNDS = {
    "seed": "[0, 2147483647]", "total_frames": "[1, 10000000000]",
    "init_random_frames": ">= 0", "frames_per_batch": "[1, 100000]", "utd_ratio": "(0, 64]",
    "batch_size": "[1, 65536]", "buffer_size": "[1, 10000000]", "lr": "(0, 1]",
    "gamma": "(0, 1]", "polyak": "[0, 1)", "alpha_init": "(0, 1000]", "reward_delay": ">= 0",
    "eval_every_frames": ">= 1", "eval_episodes": "[1, 256]", "final_eval_episodes": "[1, 10000]",
    "num_threads": "[1, 256]",
}  # fmt: skip


def check(cfg: SACConfig) -> list[str]:
    """Every problem of ``cfg``, one line each (empty: it can run)."""
    problems = [
        f"{name}={getattr(cfg, name)!r} must be {Range.parse(bound).describe()}"
        for name, bound in BOUNDS.items()
        if getattr(cfg, name) not in Range.parse(bound)  # NaN is in no range
    ]
    if cfg.task not in TASKS:
        problems.append(f"task={cfg.task!r} is not one of {list(TASKS)}")
    if cfg.variant not in VARIANTS:
        problems.append(f"variant={cfg.variant!r} is not one of {sorted(VARIANTS)}")
    if not 1 <= len(cfg.hidden) <= 8 or not all(1 <= h <= 4096 for h in cfg.hidden):
        problems.append(f"hidden={cfg.hidden} must list 1 to 8 layer sizes in [1, 4096]")
    try:  # lam_prime, tolerance and the multiplier: gentlerl's own checks
        check_group(gentleness(cfg), "gentleness")
    except ValueError as err:  # named as this recipe names them
        problems.append(str(err).split(": ", 1)[1].replace("gentleness.", ""))
    if cfg.multiplier != "none" and cfg.variant == "r":
        problems.append(f"multiplier={cfg.multiplier} weighs the penalty, which variant=r lacks")
    if isinstance(cfg.seed, int) and isinstance(cfg.total_frames, int):
        # its evaluations seed numpy with seed + 10,000 + the frames so far, below 2**32
        if cfg.seed + EVAL_SEED_OFFSET + cfg.total_frames >= 2**32:
            problems.append(
                f"seed + {EVAL_SEED_OFFSET} + total_frames must be < 2**32 (numpy's seeds), got "
                f"{cfg.seed} + {EVAL_SEED_OFFSET} + {cfg.total_frames}"
            )
    if cfg.batch_size > cfg.buffer_size:
        problems.append(f"batch_size={cfg.batch_size} must be <= buffer_size={cfg.buffer_size}")
    return problems


def make_sac_agent(env: TransformedEnv, hidden: list[int]) -> nn.ModuleList:
    """TorchRL's SAC actor (tanh-Normal) and Q-network on ``observation``."""
    spec = env.action_spec
    actor_net = nn.Sequential(
        MLP(num_cells=hidden, out_features=2 * spec.shape[-1], activation_class=nn.ReLU),
        NormalParamExtractor(scale_mapping="biased_softplus_1.0", scale_lb=1e-4),
    )
    actor = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=["observation"], out_keys=["loc", "scale"]),
        spec=spec,
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high, "tanh_loc": False},
        return_log_prob=False,
    )
    qvalue = ValueOperator(
        MLP(num_cells=hidden, out_features=1, activation_class=nn.ReLU),
        in_keys=["action", "observation"],
    )
    model = nn.ModuleList([actor, qvalue])
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        td = env.fake_tensordict()
        for net in model:  # materialise the lazy layers
            net(td)
    return model


def make_loss_module(model: nn.ModuleList, cfg: SACConfig) -> tuple[SACLoss, SoftUpdate]:
    loss = SACLoss(
        model[0], model[1], num_qvalue_nets=2, delay_qvalue=True, alpha_init=cfg.alpha_init
    )
    loss.make_value_estimator(gamma=cfg.gamma)
    return loss, SoftUpdate(loss, eps=cfg.polyak)


def gentleness(cfg: SACConfig) -> GentlenessConfig:
    """The recipe's gentleness settings as gentlerl's group."""
    return GentlenessConfig(  # gentlerl
        lam_prime=tuple(cfg.lam_prime), reward_delay=cfg.reward_delay, tolerance=cfg.tolerance,
        multiplier=cfg.multiplier, multiplier_period=cfg.multiplier_period,
        multiplier_integral_max=cfg.multiplier_integral_max, multiplier_base=cfg.multiplier_base,
        multiplier_episodes=cfg.multiplier_episodes,
    )  # fmt: skip


def make_env_and_rewards(cfg: SACConfig) -> tuple[TransformedEnv, IntrinsicRewards, SumRewards]:
    hand = make_env(cfg.task, seed=cfg.seed)
    settings = gentleness(cfg)
    variant = "r+rf" if cfg.variant == "r" else cfg.variant  # gentlerl: r logs the penalty
    rewards = IntrinsicRewards.from_env(hand, variant, settings, seed=cfg.seed)  # gentlerl
    summed = ["reward"] if cfg.variant == "r" else rewards.reward_keys  # gentlerl
    reward_sum = SumRewards(summed)  # gentlerl
    env = TransformedEnv(hand, rewards.transform.clone())  # gentlerl
    env.append_transform(RewardSum())
    env.append_transform(reward_sum)  # gentlerl
    return env, rewards, reward_sum


def steer(  # gentlerl: Method III's multiplier, from either kind of episode
    multiplier: ImpactMultiplier,
    batch: TensorDictBase,
    frames: int,
    actor: nn.Module,
    cfg: SACConfig,
) -> float:
    """The penalty's weight after this batch: from its finished episodes, or with
    ``multiplier_episodes`` from that many noise-free episodes of the actor at each PID step
    (the deployed policy's impacts; each step on episodes of its own seed)."""
    if not cfg.multiplier_episodes:
        return multiplier.observe_batch(batch, frames)  # gentlerl: the collected episodes
    if not multiplier.due(frames):  # gentlerl
        return multiplier.observe([], frames)  # gentlerl: counts the frames
    seed, n = cfg.seed + EVAL_SEED_OFFSET + frames, cfg.multiplier_episodes  # gentlerl
    episodes = actor_episodes(lambda: make_env(cfg.task), actor, n, seed)  # gentlerl
    return multiplier.observe([e["max_impact"] for e in episodes], frames)  # gentlerl


def train(cfg: SACConfig) -> dict[str, float]:
    """One SAC run; returns the final evaluation (also written to ``run_dir/final_eval.json``)."""
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.num_threads)
    run_dir = Path(cfg.run_dir or f"runs/sac/{cfg.task}/{cfg.variant}/seed{cfg.seed}")
    run_dir.mkdir(parents=True, exist_ok=True)
    env, rewards, reward_sum = make_env_and_rewards(cfg)
    model = make_sac_agent(env, cfg.hidden)
    loss, target_updater = make_loss_module(model, cfg)
    optimizer = torch.optim.Adam(loss.parameters(), lr=cfg.lr)
    rb = TensorDictReplayBuffer(
        storage=LazyTensorStorage(cfg.buffer_size), batch_size=cfg.batch_size
    )
    rb.append_transform(rewards.rescore_transform(reward_sum))  # gentlerl
    collector = Collector(
        env,
        model[0],
        frames_per_batch=cfg.frames_per_batch,
        total_frames=cfg.total_frames,
        init_random_frames=cfg.init_random_frames,
        auto_register_policy_transforms=False,  # the actor is stateless: nothing to register
    )
    frames, credit, evals = 0, 0.0, []
    bar = tqdm(total=cfg.total_frames, desc=f"sac {cfg.task} {cfg.variant} s{cfg.seed}")
    for batch in collector:
        frames += batch.numel()
        rb.extend(batch.exclude("touch_grid", ("next", "touch_grid")).reshape(-1))
        rewards.extend(batch)  # gentlerl: the models' 1-step buffer
        if rewards.multiplier is not None and frames > cfg.init_random_frames:  # gentlerl
            weight = steer(rewards.multiplier, batch, frames, model[0], cfg)  # gentlerl
            reward_sum.set_weight("penalty", weight)  # gentlerl: the policy's episodes steer
        if frames > cfg.init_random_frames:
            credit += cfg.utd_ratio * batch.numel()
            while credit >= 1:
                credit -= 1
                rewards.update()  # gentlerl: one step of each model, then its schedule
                out = loss(rb.sample())
                optimizer.zero_grad()
                (out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]).backward()
                optimizer.step()
                target_updater.step()
        collector.update_policy_weights_()
        if frames % cfg.eval_every_frames < batch.numel():
            summary = evaluate_actor(  # gentlerl: success, impact (N)
                lambda: make_env(cfg.task), model[0], cfg.eval_episodes, cfg.seed + EVAL_SEED_OFFSET
            )
            evals.append({"frames": frames, **summary})
            bar.set_postfix(eval=f"{summary['success_rate']:.2f}")
        bar.update(batch.numel())
    bar.close()
    collector.shutdown()
    with (run_dir / "evals.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(evals[0]) if evals else ["frames"])
        writer.writeheader()
        writer.writerows(evals)
    result = {
        "updates": rewards.num_updates,
        "frames": frames,
        "final_alpha": loss.log_alpha.exp().item(),  # the entropy temperature it ended at
        "penalty_weight": rewards.multiplier.weight if rewards.multiplier else 1.0,  # gentlerl
        **evaluate_actor(  # gentlerl: held-out episodes, as gentlerl evaluate
            lambda: make_env(cfg.task), model[0], cfg.final_eval_episodes, FINAL_EVAL_SEED
        ),
    }
    policy = run_dir / "actor.pt.tmp"  # the final actor, for later evaluations
    torch.save(model[0].state_dict(), policy)
    policy.replace(run_dir / "actor.pt")
    tmp = run_dir / "final_eval.json.tmp"
    tmp.write_text(json.dumps({"config": asdict(cfg), **result}, indent=1) + "\n")
    tmp.replace(run_dir / "final_eval.json")
    return result


def parse(argv: list[str]) -> SACConfig:
    """``key=value`` overrides of :class:`SACConfig`; a bad one is refused in one line."""
    if any(a in ("-h", "--help") for a in argv):
        fields = OmegaConf.to_yaml(OmegaConf.structured(SACConfig))
        print(f"usage: python recipes/sac_gentle.py [key=value ...]\n{fields}")
        sys.exit(0)
    try:
        cfg = OmegaConf.merge(OmegaConf.structured(SACConfig), OmegaConf.from_dotlist(argv))
    except Exception as error:  # omegaconf's errors span several lines
        sys.exit(f"sac_gentle: {str(error).splitlines()[0]}")
    cfg = SACConfig(**OmegaConf.to_container(cfg))
    problems = check(cfg)  # before any folder is made
    if problems:
        sys.exit(f"sac_gentle: {'; '.join(problems)}")
    return cfg


if __name__ == "__main__":
    print(json.dumps(train(parse(sys.argv[1:])), indent=1))
