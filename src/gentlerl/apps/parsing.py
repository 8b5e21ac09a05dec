"""The argument parser every ``gentlerl`` subcommand starts from."""

from __future__ import annotations

import argparse


def command_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """A subcommand's parser whose ``--help`` shows each option's default."""
    return argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
