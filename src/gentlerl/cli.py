"""The ``gentlerl`` command: ``gentlerl {train,seeds,sweep,plot,video,evaluate,claims,...}``.

Each subcommand is a module's ``main(argv, prog)`` in :mod:`gentlerl.apps`;
``gentlerl COMMAND --help`` prints that command's options with their defaults. Modules are imported
only when their command runs, so ``gentlerl --help`` and ``gentlerl plot`` start without loading
torch or MuJoCo.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from gentlerl.apps.errors import DEBUG_ENV, debugging, exit_status, interrupted, one_line

#: command -> (module with ``main(argv, prog)``, one-line description).
COMMANDS: dict[str, tuple[str, str]] = {
    "train": (
        "gentlerl.apps.train",
        "train an agent (hydra overrides: task=touch variant=r+rf+rsp seed=0 ...)",
    ),
    "seeds": (
        "gentlerl.apps.seeds",
        "train several seeds of one run in one process, their updates one batched step",
    ),
    "sweep": ("gentlerl.apps.sweeps", "run a wandb grid sweep file locally, resumably"),
    "plot": ("gentlerl.apps.plot", "paper-style figures and a summary table from runs or a sweep"),
    "video": ("gentlerl.apps.video", "MP4 / GIF of a checkpoint's evaluation rollouts"),
    "evaluate": ("gentlerl.apps.evaluate", "success, broken rate and impacts of a saved policy"),
    "claims": ("gentlerl.apps.claims", "the paper's six claims judged on a reproduce.sh grid"),
    "suite": (
        "gentlerl.apps.suite",
        "run a suite file's tasks x variants x seeds (resumable per cell), one results.csv",
    ),
    "table": (
        "gentlerl.apps.table",
        "the safe-RL table (return, max impact, success, mean ± std) of a suite's results.csv",
    ),
    "export": (
        "gentlerl.apps.export",
        "runs' final actors as small policy files (no buffer, critics)",
    ),
    "calibration": (
        "gentlerl.apps.calibration",
        "each critic head's predicted Q vs realised return",
    ),
    "forces": (
        "gentlerl.apps.forces",
        "an env's contact forces and the force unit the tolerance rule gives it",
    ),
}


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
    """Entry point of the ``gentlerl`` console script; returns the exit status.

    A command that fails prints one line on stderr and exits 1 (130 on Ctrl-C, 143 on SIGTERM); ``--debug``
    anywhere on the command line (or ``GENTLERL_DEBUG=1``) shows the traceback instead.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--debug" in argv:
        argv.remove("--debug")
        os.environ[DEBUG_ENV] = "1"
    args, rest = build_parser().parse_known_args(argv[:1])
    rest += argv[1:]
    module, _ = COMMANDS[args.command]
    try:
        status = importlib.import_module(module).main(rest, prog=f"gentlerl {args.command}")
    except (Exception, KeyboardInterrupt) as err:  # noqa: BLE001 - each failure is one line
        if debugging():
            raise
        interrupt = interrupted(err)
        if interrupt is not None:
            print(f"gentlerl {args.command}: interrupted", file=sys.stderr)
            return exit_status(interrupt)
        print(f"gentlerl {args.command}: error: {one_line(err)}", file=sys.stderr)
        return 1
    return status if isinstance(status, int) else 0  # some mains return their results


if __name__ == "__main__":
    raise SystemExit(main())
