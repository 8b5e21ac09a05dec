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
impact) differs from the recorded one. Before anything is built, the recorded config is checked
(:func:`checked_config`): the recipe's fields, types and bounds, and the folder's task, variant
and seed; the files are read through ``gentlerl.files`` (no link, FIFO or oversized file).
A row's ``wall_s`` is empty (the recipe logs no training clock), ``grouped`` 0, its date the
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


#: The largest ``final_eval.json`` read (the recipe's is a few KB) and ``actor.pt`` (the
#: recipe's largest actor, 8 layers of 4096, is about 540 MB).
MAX_FINAL_EVAL_BYTES, MAX_ACTOR_BYTES = 1 << 20, 1 << 30


def checked_config(run_dir: Path, final: Any) -> Any:
    """The recipe's config recorded in ``final`` (a loaded ``final_eval.json``), refused in one
    line naming the run before anything is built: not the recipe's fields and types, outside its
    bounds (``recipes/sac_gentle.py``'s ``check``: a 1 kB file asking for ``hidden: [40000,
    40000]`` would build 6.9 GB of networks), or another run's than its folder's
    ``<task>/<variant>/seed<k>``; its recorded numbers finite."""
    from omegaconf import OmegaConf

    sac = _recipe()
    where = f"{run_dir / 'final_eval.json'}"
    if not isinstance(final, dict) or not isinstance(final.get("config"), dict):
        raise ValueError(f"{where}: not the recipe's final evaluation (no config mapping)")
    try:
        merged = OmegaConf.merge(OmegaConf.structured(sac.SACConfig), final["config"])
        cfg = sac.SACConfig(**OmegaConf.to_container(merged))
    except Exception as err:  # noqa: BLE001 - omegaconf's errors, several lines
        raise ValueError(
            f"{where}: its config is not the recipe's ({str(err).splitlines()[0]})"
        ) from None
    if problems := sac.check(cfg):
        raise ValueError(f"{where}: its config is invalid: {'; '.join(problems)}")
    task, variant, seed = run_dir.parts[-3:]
    if (cfg.task, cfg.variant, f"seed{cfg.seed}") != (task, variant, seed):
        raise ValueError(
            f"{where}: its config is task={cfg.task} variant={cfg.variant} seed={cfg.seed}, its "
            f"folder {task}/{variant}/{seed}: not this folder's run"
        )
    numbers = {k: final.get(k) for k in (*CHECKED, "frames")}
    bad = {
        k: v for k, v in numbers.items()
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0
    }  # fmt: skip
    if bad or not isinstance(final["frames"], int):
        raise ValueError(f"{where}: {bad or numbers} must be finite numbers >= 0 (frames whole)")
    return cfg


def replay(run_dir: Path) -> tuple[dict[str, Any], list[dict[str, float]]]:
    """The run's ``final_eval.json`` and its final actor's episodes played again (a
    ``ValueError`` naming the run and the number when they are not the recorded episodes); the
    recorded config checked first (:func:`checked_config`)."""
    import torch

    from gentlerl.envs import make_env
    from gentlerl.files import folder_link_problem, open_checked, read_checked
    from gentlerl.training import actor_episodes
    from gentlerl.training.evaluation import summarize

    for folder in (run_dir, run_dir.parent, run_dir.parent.parent):
        if problem := folder_link_problem(folder, "run folder"):
            raise ValueError(problem)
    sac = _recipe()
    try:
        final = json.loads(read_checked(run_dir / "final_eval.json", MAX_FINAL_EVAL_BYTES))
    except json.JSONDecodeError as err:
        raise ValueError(f"{run_dir / 'final_eval.json'}: not JSON ({err})") from None
    cfg = checked_config(run_dir, final)
    actor = sac.make_sac_agent(sac.make_env_and_rewards(cfg)[0], cfg.hidden)[0]
    try:
        with open_checked(run_dir / "actor.pt", MAX_ACTOR_BYTES, binary=True) as f:
            actor.load_state_dict(torch.load(f, weights_only=True))
    except (RuntimeError, KeyError, TypeError, EOFError, AttributeError) as err:
        reason = str(err).strip().splitlines()[0][:160] if str(err).strip() else type(err).__name__
        raise ValueError(f"{run_dir / 'actor.pt'}: not this config's actor ({reason})") from None
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
    final, episodes = replay(run_dir)  # its config is its folder's task, variant and seed
    task, variant = run_dir.parts[-3], run_dir.parts[-2]
    written = (run_dir / "final_eval.json").lstat().st_mtime
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
