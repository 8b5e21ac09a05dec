"""The paper's six claims judged by the pre-registered criteria of docs/REPRODUCTION.md.

    python -m gentlerl.claims [NAME=]RUNS_ROOT ... [--final-evals DIR] [--seeds 0,1]
                              [--markdown OUT.md]

``RUNS_ROOT`` holds the three sweeps of ``recipes/reproduce.sh`` (``fig3_noreward_impacts``,
``fig4_touch``, ``fig4_fragile``, each a folder of run directories). "Final success" is the
success rate of each run's last actor over the 20 episodes of ``python -m gentlerl.evaluate
checkpoint.pt --episodes 20 --seed 0 --json`` that ``reproduce.sh`` writes to
``DIR/<sweep>/final_eval.jsonl``, averaged over seeds; without that file a run's last in-loop
evaluation is used and the report says so. Impacts of the successful final-policy rollouts
(claim 5, :func:`gentlerl.plot.successful_final_impacts`) come from the same 20 episodes
(``final_eval_episodes.csv`` next to each checkpoint, written by ``reproduce.sh``), else from
the run's last in-loop evaluation (``eval_episodes.csv``). Rollouts "after the switch" are the training
rollouts logged after :func:`gentlerl.plot.intrinsic_start`; "touching" means max impact > 0.

A verdict is ``reproduced`` when every condition of the claim holds, ``partly`` when its weaker
condition holds, otherwise ``not reproduced``; a claim whose runs are missing is ``no data``.

Several roots (the rows of an ablation, e.g. ``changes=runs/cpu/changes
no-nll-floor=runs/cpu/no-nll-floor``) give one verdict column per root, then each root's table;
``--seeds`` judges only the runs of those seeds, so that rows with different seed counts can be
compared on the seeds they share.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gentlerl.plot import Run, find_runs, successful_final_impacts
from gentlerl.summary import after_switch_columns

SWEEPS = ("fig3_noreward_impacts", "fig4_touch", "fig4_fragile")
NAN = float("nan")
_EMPTY = {"rollouts": 0, "touch": NAN, "median": NAN, "in_5_15": NAN, "below_5": NAN}


@dataclass(frozen=True)
class Verdict:
    claim: int
    verdict: str
    numbers: str


def touch_stats(runs: Sequence[Run]) -> dict[str, float]:
    """The criteria's names for :func:`gentlerl.summary.after_switch_columns`: rollout count,
    touching share, and the median / share in [5, 15] N / share below 5 N of the max impact of
    the touching rollouts after the switch."""
    cols = after_switch_columns(runs)
    return {
        "rollouts": cols["rollouts_after_switch"],
        "touch": cols["touching_share_after_switch"],
        "median": cols["median_impact_after_switch"],
        "in_5_15": cols["share_5_15N_after_switch"],
        "below_5": cols["share_under_5N_after_switch"],
    }


def final_success(runs: Sequence[Run], evals: dict[str, float]) -> float:
    """Mean over seeds of each run's final success (``evals[run dir]``, else its last evaluation)."""
    values = []
    for run in runs:
        key = str(run.path.resolve())
        if key in evals:
            values.append(evals[key])
        elif "eval/success_rate" in run.scalars and len(run.scalars["eval/success_rate"][1]):
            values.append(float(run.scalars["eval/success_rate"][1][-1]))
    return float(np.mean(values)) if values else NAN


def first_success_frame(runs: Sequence[Run], threshold: float = 0.8) -> float:
    """Mean over seeds of the first frame with evaluation success >= ``threshold`` (inf if a seed
    never gets there: such a variant is not "as fast")."""
    frames = []
    for run in runs:
        x, y = run.scalars.get("eval/success_rate", (np.zeros(0), np.zeros(0)))
        hits = x[y >= threshold]
        frames.append(float(hits[0]) if len(hits) else math.inf)
    return float(np.mean(frames)) if frames else NAN


def _grade(full: bool, partly: bool, *inputs: float) -> str:
    if any(isinstance(v, float) and math.isnan(v) for v in inputs):
        return "no data"
    return "reproduced" if full else "partly" if partly else "not reproduced"


class _Grid:
    """The numbers of one grid: per ``(task, variant)`` the pooled seeds' statistics."""

    def __init__(self, groups: dict[tuple[str, str], list[Run]], evals: dict[str, float]):
        self.groups = groups
        self.stats = {key: touch_stats(runs) for key, runs in groups.items()}
        self.success = {key: final_success(runs, evals) for key, runs in groups.items()}

    def s(self, task: str, variant: str) -> dict[str, float]:
        return self.stats.get((task, variant), _EMPTY)

    def f(self, task: str, variant: str) -> float:
        return self.success.get((task, variant), NAN)

    def runs(self, task: str, variant: str) -> list[Run]:
        return self.groups.get((task, variant), [])


def claim1(g: _Grid) -> Verdict:
    """`rs` without penalty hits with 5-15 N per rollout."""
    rs = g.s("explore", "rs")
    full = 5 <= rs["median"] <= 15 and rs["in_5_15"] >= 0.5
    numbers = f"`rs` median {rs['median']:.2f} N, {rs['in_5_15']:.0%} in [5, 15] N"
    return Verdict(1, _grade(full, rs["median"] >= 3, rs["median"]), numbers)


def claim2(g: _Grid) -> Verdict:
    """With the impact penalty, impacts mostly 0-5 N."""
    rs, fs, fp = g.s("explore", "rs"), g.s("explore", "rf+rs"), g.s("explore", "rf+rsp")
    below = min(fs["below_5"], fp["below_5"])
    full = below >= 0.8 and max(fs["median"], fp["median"]) < rs["median"]
    numbers = (
        f"below 5 N: `rf+rs` {fs['below_5']:.0%}, `rf+rsp` {fp['below_5']:.0%}; medians "
        f"{fs['median']:.2f} / {fp['median']:.2f} N vs `rs` {rs['median']:.2f} N"
    )
    return Verdict(2, _grade(full, below >= 0.65, below, rs["median"]), numbers)


def claim3(g: _Grid) -> Verdict:
    """Penalty surprise touches more, and more gently, than dynamics surprise."""
    fs, fp = g.s("explore", "rf+rs"), g.s("explore", "rf+rsp")
    more = fp["touch"] - fs["touch"] >= 0.10
    gentler = fp["median"] < fs["median"]
    numbers = (
        f"touching `rf+rsp` {fp['touch']:.0%} vs `rf+rs` {fs['touch']:.0%}; median "
        f"{fp['median']:.2f} vs {fs['median']:.2f} N"
    )
    return Verdict(3, _grade(more and gentler, more or gentler, fp["touch"], fs["touch"]), numbers)


def claim4(g: _Grid) -> Verdict:
    """`r+rf` and `r+rf+rs` fail touch (the no-contact optimum)."""
    rf, rfs = g.f("touch", "r+rf"), g.f("touch", "r+rf+rs")
    touch = {v: g.s("touch", v)["touch"] for v in ("r+rf", "r+rf+rs", "r+rf+rsp")}
    fewer = max(touch["r+rf"], touch["r+rf+rs"]) < touch["r+rf+rsp"]
    numbers = (
        f"final success `r+rf` {rf:.2f}, `r+rf+rs` {rfs:.2f}; touching after the switch "
        f"{touch['r+rf']:.0%} / {touch['r+rf+rs']:.0%} vs `r+rf+rsp` {touch['r+rf+rsp']:.0%}"
    )
    return Verdict(4, _grade(max(rf, rfs) <= 0.2 and fewer, max(rf, rfs) <= 0.5, rf, rfs), numbers)


def claim5(g: _Grid) -> Verdict:
    """`r+rf+rsp` learns touch about as fast as `r`, with lower impact."""
    rsp, r = g.f("touch", "r+rf+rsp"), g.f("touch", "r")
    first_rsp = first_success_frame(g.runs("touch", "r+rf+rsp"))
    first_r = first_success_frame(g.runs("touch", "r"))
    imp_rsp = _median(successful_final_impacts(g.runs("touch", "r+rf+rsp")))
    imp_r = _median(successful_final_impacts(g.runs("touch", "r")))
    full = rsp >= 0.8 and first_rsp <= first_r + 10_000 and imp_rsp <= 0.75 * imp_r
    numbers = (
        f"final success `r+rf+rsp` {rsp:.2f} vs `r` {r:.2f}; first eval >= 0.8 at "
        f"{first_rsp:.0f} vs {first_r:.0f} frames (mean over seeds); median max impact of "
        f"successful final rollouts {imp_rsp:.2f} vs {imp_r:.2f} N"
    )
    return Verdict(5, _grade(full, rsp >= 0.8 and imp_rsp < imp_r, rsp, r), numbers)


def claim6(g: _Grid) -> Verdict:
    """`r` fails the fragile block, `r+rf+rsp` learns it; ICM fails both tasks."""
    fr, frsp = g.f("fragile", "r"), g.f("fragile", "r+rf+rsp")
    icm_t, icm_f = g.f("touch", "r+icm"), g.f("fragile", "r+icm")
    full = fr <= 0.5 and frsp >= 0.8 and max(icm_t, icm_f) <= 0.5
    numbers = (
        f"fragile final success `r` {fr:.2f}, `r+rf+rsp` {frsp:.2f}; `r+icm` {icm_t:.2f} "
        f"(touch) / {icm_f:.2f} (fragile)"
    )
    return Verdict(6, _grade(full, frsp - fr >= 0.3, fr, frsp, icm_t, icm_f), numbers)


CLAIMS = (claim1, claim2, claim3, claim4, claim5, claim6)


def judge(
    groups: dict[tuple[str, str], list[Run]], evals: dict[str, float] | None = None
) -> list[Verdict]:
    """Every claim's verdict from runs grouped by ``(task, variant)`` (seeds pooled)."""
    grid = _Grid(groups, evals or {})
    return [claim(grid) for claim in CLAIMS]


def _median(values: np.ndarray) -> float:
    return float(np.median(values)) if len(values) else NAN


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
        for number, line in enumerate(path.read_text().splitlines(), 1):
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


def _row(spec: str) -> tuple[str, Path]:
    name, sep, path = spec.rpartition("=")
    return (name if sep else spec), Path(path)


def _seeds(text: str) -> set[int]:
    try:
        return {int(s) for s in text.split(",")}
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seeds takes integers like 0,1; got {text!r}") from None


def _judge_root(
    root: Path, evals: dict[str, float], seeds: set[int] | None
) -> tuple[list[Verdict], int]:
    runs = [r for r in find_runs([root]) if seeds is None or int(r.config["seed"]) in seeds]
    if not runs:
        raise FileNotFoundError(f"no runs of seeds {sorted(seeds or ())} under {root}")
    return judge(group_by_variant(runs), evals), len(runs)


def main(argv: Sequence[str] | None = None, prog: str = "python -m gentlerl.claims") -> None:
    """Print (and with ``--markdown``, write) the verdict table of one or several grids."""
    parser = argparse.ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "runs",
        nargs="+",
        type=_row,
        help="[NAME=]the --out/<scale>/<method> folder of reproduce.sh",
    )
    parser.add_argument("--final-evals", type=Path, help="folder with <sweep>/final_eval.jsonl")
    parser.add_argument("--seeds", type=_seeds, help="judge only these seeds, e.g. 0,1")
    parser.add_argument("--markdown", type=Path, help="also write the table to this file")
    args = parser.parse_args(argv)
    evals = load_final_evals(args.final_evals) if args.final_evals else {}
    source = "final_eval.jsonl (20 episodes)" if evals else "each run's last in-loop evaluation"
    seeds = f" (seeds {','.join(map(str, sorted(args.seeds)))})" if args.seeds else ""
    rows, tables = {}, []
    for name, root in args.runs:
        rows[name], n = _judge_root(root, evals, args.seeds)
        tables.append(
            f"{format_verdicts(rows[name])}\n{n} runs{seeds} under {root}; final success from "
            f"{source}.\n"
        )
    table = tables[0]
    if len(rows) > 1:
        table = format_comparison(rows) + "".join(
            f"\n### {name}\n\n{t}" for name, t in zip(rows, tables, strict=True)
        )
    print(table, end="")
    if args.markdown:
        tmp = args.markdown.with_name(f".{args.markdown.name}.tmp")
        tmp.write_text(table)
        tmp.replace(args.markdown)


if __name__ == "__main__":
    main()
