"""The paper's six claims as pre-registered criteria, one function per claim.

A verdict per claim from runs grouped by ``(task, variant)``, seeds pooled (:func:`judge`, one
``claimN`` function per claim). A verdict is ``reproduced`` when every condition of the claim
holds, ``partly`` when its weaker condition holds, otherwise ``not reproduced``; a claim whose runs
are missing is ``no data``. ``gentlerl claims`` applies them (:mod:`gentlerl.analysis.claims`).

The project's own experiments (the SAC grid, GentleBench, Method III) keep their criteria in the
checkout's ``experiments/`` folder, not in the library.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gentlerl.analysis.runs import EVAL_SUCCESS, Run, successful_final_impacts
from gentlerl.analysis.summary import after_switch_columns

NAN = float("nan")
_EMPTY = {"rollouts": 0, "touch": NAN, "median": NAN, "in_5_15": NAN, "below_5": NAN}


@dataclass(frozen=True)
class Verdict:
    claim: int
    verdict: str
    numbers: str


def touch_stats(runs: Sequence[Run]) -> dict[str, float]:
    """The criteria's names for :func:`gentlerl.analysis.summary.after_switch_columns`: rollout
    count, touching share, and the median / share in [5, 15] N / share below 5 N of the max impact
    of the touching rollouts after the switch."""
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
        elif len(run.scalars.get(EVAL_SUCCESS, ((), ()))[1]):
            values.append(float(run.scalars[EVAL_SUCCESS][1][-1]))
    return float(np.mean(values)) if values else NAN


def first_success_frame(runs: Sequence[Run], threshold: float = 0.8) -> float:
    """Mean over seeds of the first frame with evaluation success >= ``threshold`` (inf if a seed
    never gets there: such a variant is not "as fast")."""
    frames = []
    for run in runs:
        x, y = run.scalars.get(EVAL_SUCCESS, (np.zeros(0), np.zeros(0)))
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


#: Names that left this module in 0.2.0 -> the experiment that holds them now.
_MOVED = {
    "sac_verdict": "experiments/sac_grid/criteria.py",
    "gentlebench_verdict": "experiments/gentlebench/criteria.py",
    "GENTLEBENCH_R_LEARNS": "experiments/gentlebench/criteria.py",
}


def __getattr__(name: str) -> object:
    if name in _MOVED:
        raise ImportError(
            f"gentlerl.analysis.criteria.{name} moved out of the library in 0.2.0: it is in "
            f"{_MOVED[name]} of a checkout"
        )
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
