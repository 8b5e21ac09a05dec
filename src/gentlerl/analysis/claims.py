"""The six claims judged on grids of runs: the final evaluations read, the runs grouped, the
verdicts formatted (the criteria are :mod:`gentlerl.analysis.criteria`; the ``gentlerl claims``
command is :mod:`gentlerl.apps.claims`)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from gentlerl.analysis.criteria import Verdict
from gentlerl.analysis.runs import Run
from gentlerl.files import read_checked


def load_final_evals(folder: Path) -> dict[str, float]:
    """``{run dir: success_rate}`` from every ``final_eval.jsonl`` under ``folder``; a missing
    folder, a folder without one, or a line that is not such a JSON row is an error naming it."""
    if not folder.is_dir():
        raise FileNotFoundError(f"--final-evals {folder}: no such directory")
    paths = sorted(folder.rglob("final_eval.jsonl"))
    if not paths:
        raise FileNotFoundError(f"--final-evals {folder}: no final_eval.jsonl under it")
    out = {}
    for path in paths:
        for number, line in enumerate(read_checked(path, errors="replace").splitlines(), 1):
            if line.strip():
                out.update([_final_eval(line, f"{path}:{number}")])
    return out


def _final_eval(line: str, where: str) -> tuple[str, float]:
    try:
        row = json.loads(line)
        rate = float(row["success_rate"])
        policy = str(Path(row["policy"]).resolve().parent)
    except (ValueError, TypeError, KeyError) as err:
        reason = f"lacks {err}" if isinstance(err, KeyError) else "is not a JSON object"
        raise ValueError(
            f"{where} {reason}: expected a `gentlerl evaluate --json` row with policy and "
            "success_rate"
        ) from None
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"{where}: success_rate={rate} is not in [0, 1]")
    return policy, rate


def group_by_variant(runs: Sequence[Run]) -> dict[tuple[str, str], list[Run]]:
    """Runs keyed by ``(task, variant)``; seeds (and lambda'_2 values, if several) pooled."""
    groups: dict[tuple[str, str], list[Run]] = {}
    for run in runs:
        groups.setdefault((run.config["task"], run.config["variant"]), []).append(run)
    return groups


def format_verdicts(verdicts: Sequence[Verdict]) -> str:
    lines = ["| # | verdict | numbers |", "| --- | --- | --- |"]
    lines += [f"| {v.claim} | **{v.verdict}** | {v.numbers} |" for v in verdicts]
    return "\n".join(lines) + "\n"


def format_comparison(rows: dict[str, Sequence[Verdict]]) -> str:
    """One verdict column per row (e.g. the rows of an ablation), claims down the side."""
    lines = ["| # | " + " | ".join(rows) + " |", "| --- |" + " --- |" * len(rows)]
    for i, claim in enumerate(next(iter(rows.values()))):
        lines.append(f"| {claim.claim} | " + " | ".join(v[i].verdict for v in rows.values()) + " |")
    return "\n".join(lines) + "\n"
