"""The ``gentlerl`` command: ``gentlerl {train,sweep,plot,video,evaluate} ...``.

Each subcommand is a module's ``main(argv, prog)``; ``gentlerl COMMAND --help`` prints that
command's options with their defaults. Modules are imported only when their command runs, so
``gentlerl --help`` and ``gentlerl plot`` start without loading torch or MuJoCo.
"""

from __future__ import annotations

import argparse
import importlib
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path

#: The hydra training app (one config per variant and scale under ``recipes/config``).
TRAIN_SCRIPT = Path(__file__).resolve().parents[2] / "recipes" / "train.py"

TRAIN_HELP = """usage: gentlerl train [KEY=VALUE ...] [-m]

Train an agent (hydra app, recipes/train.py); every KEY=VALUE overrides the config shown below.
  task=explore|touch|fragile   variant=<group option>   scale=cpu|paper   seed=<int>
  -m, --multirun               a local sweep over comma-separated values (variant=r,r+rf seed=0,1)
Examples:
  gentlerl train                                   # the default recipe (touch, r+rf+rsp, cpu)
  gentlerl train task=fragile variant=r+rf+rsp lam_prime=[2,1.5] seed=1
  gentlerl train resume=true run_dir=runs/touch/r+rf+rsp/seed0
"""

#: command -> (module with ``main(argv, prog)``, one-line description); ``None``: the hydra app.
COMMANDS: dict[str, tuple[str | None, str]] = {
    "train": (None, "train an agent (hydra overrides: task=touch variant=r+rf+rsp seed=0 ...)"),
    "sweep": ("gentlerl.sweeps", "run a wandb grid sweep file locally, resumably"),
    "plot": ("gentlerl.figures", "paper-style figures and a summary table from runs or a sweep"),
    "video": ("gentlerl.video", "MP4 / GIF of a checkpoint's evaluation rollouts"),
    "evaluate": ("gentlerl.evaluate", "success, broken rate and impacts of a saved policy"),
}


def run_train(argv: Sequence[str]) -> None:
    """Run the hydra app with ``argv`` as its command line (help: task choices, then hydra's)."""
    if not TRAIN_SCRIPT.is_file():
        raise SystemExit(
            f"gentlerl train runs {TRAIN_SCRIPT}, which this install does not have: install "
            "gentlerl from its source tree (pip install -e .)"
        )
    if any(a in ("-h", "--help") for a in argv):
        print(TRAIN_HELP)
        argv = ["--help"]
    saved = sys.argv
    sys.argv = ["gentlerl train", *argv]
    try:
        runpy.run_path(str(TRAIN_SCRIPT), run_name="__main__")
    finally:
        sys.argv = saved


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gentlerl",
        description="Gentle object manipulation with curiosity-driven deep RL, for TorchRL.",
        epilog="`gentlerl COMMAND --help` lists a command's options and their defaults.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (_, description) in COMMANDS.items():
        commands.add_parser(name, help=description, add_help=False)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gentlerl`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args, rest = build_parser().parse_known_args(argv[:1])
    rest += argv[1:]
    module, _ = COMMANDS[args.command]
    if module is None:
        run_train(rest)
        return 0
    status = importlib.import_module(module).main(rest, prog=f"gentlerl {args.command}")
    return status if isinstance(status, int) else 0  # some mains return their results


if __name__ == "__main__":
    raise SystemExit(main())
