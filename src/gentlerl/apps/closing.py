"""What ``gentlerl train`` prints when a run ends: its final numbers, where its files are, and
the commands that plot and evaluate it."""

from __future__ import annotations

import math
import shlex
from collections.abc import Mapping
from pathlib import Path

from gentlerl.config.layout import RunLayout

#: Episodes of the evaluation the closing lines suggest (the criteria's held-out count).
EVALUATE_EPISODES = 20


def closing_text(summary: Mapping[str, float], run_dir: str | Path, unit: str = "N") -> str:
    """Three lines: the final evaluation (``max_impact_mean`` in ``unit``; outcomes the env does
    not define, NaN in the evaluations of older runs, left out), the run directory with its
    policy and logs, and the ``gentlerl plot`` and ``gentlerl evaluate`` commands for it."""
    numbers = [
        f"{k}={v:.3f}" + (f" {unit}" if k == "max_impact_mean" else "")
        for k, v in summary.items()
        if not math.isnan(v)
    ]
    layout = RunLayout(run_dir)
    run = shlex.quote(str(layout.root))
    figures = shlex.quote(str(layout.root / "figures"))
    policy = shlex.quote(str(layout.best_policy))
    logs = layout.scalars.relative_to(layout.root)
    return "\n".join(
        [
            " ".join(numbers),
            f"run directory {run}: policy {layout.best_policy.name} (best evaluation; last: "
            f"{layout.checkpoint.name}), logs {logs}/*.csv and {layout.eval_episodes.name}",
            f"figures: gentlerl plot {run} -o {figures}    evaluate: gentlerl evaluate "
            f"{policy} --episodes {EVALUATE_EPISODES}",
        ]
    )
