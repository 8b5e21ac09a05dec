"""The SAC grid's runs as a suite's results file, for ``gentlerl table``'s safe-RL form.

    python experiments/sac_grid/results.py runs/sac_after_fix --suite sac_after_fix \\
        --out experiments/sac_grid/after_fix/results.csv
    gentlerl table experiments/sac_grid/after_fix/results.csv

``experiments/sac_grid/grid.sh`` runs ``recipes/sac_gentle.py``, a program of its own that the
suite harness (``gentlerl suite run``) does not run. Its runs keep the final evaluation's
medians (``final_eval.json``); a results row (:data:`gentlerl.analysis.results.RESULT_COLUMNS`)
holds the episodes' means. So each run's final actor (``actor.pt``) plays again the held-out
episodes its ``final_eval.json`` summarises (the same count, the same seed: the same episodes),
and the replay is refused when any of :data:`CHECKED` (success and broken rates, median max
impact) differs from the recorded one. A row's ``wall_s`` is empty (the recipe logs no training clock), ``grouped`` 0, its date the
day ``final_eval.json`` was written, its ``version`` / ``commit`` the code converting it.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: The summary numbers a replay must give again, as ``final_eval.json`` recorded them.
CHECKED = ("success_rate", "broken_rate", "median_max_impact")


def _recipe() -> ModuleType:
    """``recipes/sac_gentle.py`` (a script, not a package) as a module."""
    if "sac_gentle" not in sys.modules:
        spec = importlib.util.spec_from_file_location("sac_gentle", ROOT / "recipes/sac_gentle.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules["sac_gentle"] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
    return sys.modules["sac_gentle"]


def replay(run_dir: Path) -> tuple[dict[str, Any], list[dict[str, float]]]:
    """The run's ``final_eval.json`` and its final actor's episodes played again (a
    ``ValueError`` naming the run and the number when they are not the recorded episodes)."""
    import torch

    from gentlerl.envs import make_env
    from gentlerl.training import actor_episodes
    from gentlerl.training.evaluation import summarize

    sac = _recipe()
    final = json.loads((run_dir / "final_eval.json").read_text())
    cfg = sac.SACConfig(**final["config"])
    actor = sac.make_sac_agent(sac.make_env_and_rewards(cfg)[0], cfg.hidden)[0]
    actor.load_state_dict(torch.load(run_dir / "actor.pt", weights_only=True))
    episodes = actor_episodes(
        lambda: make_env(cfg.task), actor, cfg.final_eval_episodes, sac.FINAL_EVAL_SEED
    )
    again = summarize(episodes)
    for key in CHECKED:
        if not math.isclose(again[key], final[key], rel_tol=1e-6, abs_tol=1e-9):
            raise ValueError(
                f"{run_dir}: the replay's {key} is {again[key]!r}, final_eval.json's "
                f"{final[key]!r}: not the episodes it recorded"
            )
    return final, episodes


def run_row(run_dir: Path, suite: str, stamp: dict[str, str]) -> dict[str, Any]:
    """One results row of the run at ``ROOT/<task>/<variant>/seed<k>`` (its labels: the grid's)."""
    final, episodes = replay(run_dir)
    task, variant = run_dir.parts[-3], run_dir.parts[-2]
    written = (run_dir / "final_eval.json").stat().st_mtime
    return {
        "suite": suite, "cell": f"{task}/{variant}", "task": task, "variant": variant,
        "seed": final["config"]["seed"], "frames": final["frames"],
        "return": sum(e["return"] for e in episodes) / len(episodes),
        "success_rate": final["success_rate"], "broken_rate": final["broken_rate"],
        "max_impact": sum(e["max_impact"] for e in episodes) / len(episodes),
        "wall_s": None, "grouped": 0, **stamp,
        "date": datetime.fromtimestamp(written, timezone.utc).strftime("%Y-%m-%d"),
    }  # fmt: skip


def grid_rows(root: Path, suite: str) -> list[dict[str, Any]]:
    """Every finished run's row under ``root`` (tasks, variants and seeds in sorted order)."""
    from gentlerl.apps.suite import code_version

    runs = sorted(path.parent for path in root.glob("*/*/seed*/final_eval.json"))
    if not runs:
        raise FileNotFoundError(f"no <task>/<variant>/seed<k>/final_eval.json under {root}")
    stamp = code_version()
    return [run_row(run, suite, stamp) for run in runs]


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="experiments/sac_grid/results.py", description=__doc__.splitlines()[0]
    )
    parser.add_argument("runs", type=Path, help="the grid's --out folder (runs/sac_after_fix)")
    parser.add_argument("--suite", required=True, help="the rows' suite name (sac_after_fix)")
    parser.add_argument("--out", type=Path, required=True, help="the results file to write (.csv)")
    args = parser.parse_args(argv)
    from gentlerl.analysis.results import write_results
    from gentlerl.apps.outputs import check_output_file
    from gentlerl.apps.suite_files import LABEL

    try:
        if not LABEL.fullmatch(args.suite):
            raise ValueError(f"--suite {args.suite!r} is not a label (letters, digits, '_.+-')")
        check_output_file(args.out, (".csv",))
        if not args.runs.is_dir():
            raise FileNotFoundError(f"{args.runs}: no such directory")
        rows = grid_rows(args.runs, args.suite)
    except (OSError, ValueError) as err:
        sys.exit(f"experiments/sac_grid/results.py: {err}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_results(args.out, rows)
    print(f"{args.out}: {len(rows)} runs; their table: gentlerl table {args.out}")


if __name__ == "__main__":
    if __package__ in (None, ""):  # run as a script: the checkout's root on the path
        sys.path.insert(0, str(ROOT))
    main()
