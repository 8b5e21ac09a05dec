"""The argument parser every ``gentlerl`` subcommand starts from."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any


def command_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A subcommand's parser whose ``--help`` shows each option's default."""
    return argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )


def add_renamed(parser: argparse.ArgumentParser, old: str, new: str) -> None:
    """Refuse the option ``old`` in one line naming ``new`` (kept out of ``--help``)."""

    class Renamed(argparse.Action):
        def __call__(
            self,
            parser: argparse.ArgumentParser,
            namespace: argparse.Namespace,
            values: str | Sequence[Any] | None,
            option_string: str | None = None,
        ) -> None:
            raise SystemExit(f"{parser.prog}: {old} is now {new}")

    parser.add_argument(
        old, action=Renamed, nargs="?", default=argparse.SUPPRESS, help=argparse.SUPPRESS
    )
