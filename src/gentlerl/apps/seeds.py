"""Train several seeds of one run together in one process (a seed group): ``gentlerl seeds``.

    gentlerl seeds 0 1 2                                       # the default recipe, three seeds
    gentlerl seeds 0 1 2 3 4 --set task=fragile --set learner.device=cuda --out runs/fragile5

Each seed is a run of its own, in ``OUT/seed<seed>`` (without ``--out``: where ``gentlerl train``
puts it, ``runs/<task>/<variant>/seed<seed>``): its env stream, exploration noise, replay,
reward models, evaluations, logs and checkpoint, which ``gentlerl plot`` and ``gentlerl
evaluate`` read and ``gentlerl train run_dir=... resume=true`` continues alone. The seeds'
reward models and D4PG learners take their updates as one vmapped step
(:class:`~gentlerl.training.seed_group.SeedGroup`): on a GPU learner that is the point (five
seeds' learner step measured at 0.60x one seed's rate on an H200); on a CPU a group costs about
what its seeds cost one after the other. ``--set`` items are the config fields of ``gentlerl
train --help``, read and checked as a sweep's; ``seed``, ``run_dir`` and ``resume`` are the
command's own. A group is refused in one line before any folder is made: a setting it does not
batch (``gentleness.multiplier``), a run directory that holds a checkpoint (a group does not
resume; one stopped before its first checkpoint starts again), repeated seeds, more than
``MAX_SEEDS`` (64) seeds, and a group whose replay buffers would not fit the machine's free
memory (64 seeds of the default recipe keep at least 40.7 GB of transitions).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from gentlerl.apps.parsing import command_parser
from gentlerl.apps.sweep_files import nested_overrides, parse_set
from gentlerl.config.limits import MAX_SEEDS
from gentlerl.training.config import TrainConfig, make_config

#: Settings the command sets per seed, refused in ``--set``.
PER_SEED = ("seed", "run_dir", "resume")


def group_configs(
    seeds: Sequence[int], items: Sequence[str], out: str | Path | None = None
) -> list[TrainConfig]:
    """One validated config per seed: the ``--set`` ``items`` on the CPU preset (or their
    ``scale``), the seed, its run directory (``out/seed<seed>``, or ``gentlerl train``'s)."""
    if len(set(seeds)) != len(seeds) or not seeds:
        raise ValueError(f"seeds must be one or more different integers, got {list(seeds)}")
    if len(seeds) > MAX_SEEDS:
        raise ValueError(
            f"{len(seeds)} seeds: a group holds at most {MAX_SEEDS} (each seed's replay, models "
            "and collector live in the one process); split them into several groups"
        )
    for item in items:
        if (key := item.partition("=")[0]) in PER_SEED:
            raise ValueError(
                f"--set {item!r}: {key} is set per seed by gentlerl seeds (SEEDS, --out)"
            )
    overrides = nested_overrides(parse_set(items))
    scale = overrides.pop("scale", "cpu")
    if out is None:  # gentlerl train's folders: runs/<task>/<variant>/seed<seed>
        from gentlerl.apps.train import run_name

        base = make_config(scale, **overrides)
        out = Path("runs") / run_name(base.task, base.env.name) / base.variant
    return [
        # resume="auto": a group stopped before its first checkpoint starts again where it was
        # (a run directory with a checkpoint is refused: a group does not resume)
        make_config(
            scale, **overrides, seed=seed, run_dir=str(Path(out) / f"seed{seed}"), resume="auto"
        )
        for seed in seeds
    ]


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl seeds") -> list[dict[str, float]]:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("seeds", type=int, nargs="+", metavar="SEED", help="the group's seeds")
    parser.add_argument(
        "--set", action="append", default=[], metavar="FIELD=VALUE",
        help="a config field for every seed (gentlerl train --help lists them); repeatable",
    )  # fmt: skip
    parser.add_argument(
        "--out", help="the runs go to OUT/seed<SEED>; none: runs/<task>/<variant>/seed<SEED>"
    )
    args = parser.parse_args(argv)
    from gentlerl.apps.train import quiet_torchrl_info

    quiet_torchrl_info()  # before TorchRL is imported
    cfgs = group_configs(args.seeds, args.set, args.out)
    from gentlerl.apps.closing import closing_text
    from gentlerl.training.logging import force_unit
    from gentlerl.training.seed_group import train_seeds

    summaries = train_seeds(cfgs)  # refused in one line before any folder (SeedGroup)
    for cfg, summary in zip(cfgs, summaries, strict=True):
        unit = force_unit(cfg.env.force_scale)
        print(f"seed {cfg.seed}: {closing_text(summary, cfg.run_dir, unit)}")
    return summaries
