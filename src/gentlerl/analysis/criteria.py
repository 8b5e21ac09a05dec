"""The pre-registered criteria as code, one function per rule.

- the six claims of docs/REPRODUCTION.md: a verdict per claim from runs grouped by
  ``(task, variant)``, seeds pooled (:func:`judge`, one ``claimN`` function per claim). A verdict
  is ``reproduced`` when every condition of the claim holds, ``partly`` when its weaker condition
  holds, otherwise ``not reproduced``; a claim whose runs are missing is ``no data``;
- the SAC grid of docs/SAC.md: :func:`sac_verdict`, one per task;
- GentleBench of docs/GENTLEBENCH.md: :func:`gentlebench_verdict`, one per task and variant;
- its Method III amendments: :mod:`gentlerl.analysis.method3_criteria`.

The tables these rules judge are :mod:`gentlerl.analysis.grid_tables` and
:mod:`gentlerl.analysis.method3` (``gentlerl table``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
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


#: GentleBench: below this median return ``r`` has not learned its task (2 % of dm_control's 1000).
GENTLEBENCH_R_LEARNS = 20.0


def gentlebench_verdict(r: Mapping[str, float], other: Mapping[str, float]) -> str:
    """docs/GENTLEBENCH.md's label for one variant against ``r`` on the same task.

    Each row holds ``median_return`` (median over seeds of the per-run mean return) and
    ``median_impact`` (median per-episode max impact, N). *keeps the return*: ``other``'s median
    return >= 0.8 x ``r``'s; *gentler*: its median impact <= 0.5 x ``r``'s. Both: "gentle and as
    good"; only *gentler*: "gentle but worse"; only *keeps*: "no gentleness gain"; else "neither".
    When ``r``'s median return is below :data:`GENTLEBENCH_R_LEARNS` the return test says nothing:
    "not judged: r does not learn at 30k" (with "; gentler" when that test holds).
    """
    gentler = other["median_impact"] <= 0.5 * r["median_impact"]
    if r["median_return"] < GENTLEBENCH_R_LEARNS:
        return "not judged: r does not learn at 30k" + ("; gentler" if gentler else "")
    keeps = other["median_return"] >= 0.8 * r["median_return"]
    return {
        (True, True): "gentle and as good",
        (False, True): "gentle but worse",
        (True, False): "no gentleness gain",
        (False, False): "neither",
    }[(keeps, gentler)]


def sac_verdict(task: str, r: Mapping[str, float], rsp: Mapping[str, float]) -> str:
    """docs/SAC.md's verdict on one task from the ``r`` and ``r+rf+rsp`` rows of SAC.

    Each row holds ``mean_success`` (mean over seeds of the final success) and
    ``successful_impact`` (median over seeds of the median max impact of successful episodes, N;
    nan when none succeeded). Both below 0.5 success: "SAC does not learn the task at this
    budget". Success criterion: ``rsp``'s >= max(0.8 x ``r``'s, 0.5); impact criterion: ``rsp``'s
    <= 0.75 x ``r``'s (claim 5's). Both: "gentleness transfers"; impact only: "gentler but less
    successful"; else "not gentler". When ``r`` never succeeded (no impact to compare, a case added
    after the first runs) the words say whether ``rsp`` is more successful. On ``fragile``, ``rsp``
    ahead of ``r`` by >= 0.3 success adds "; helps on the fragile block" (claim 6's).
    """
    if r["mean_success"] < 0.5 and rsp["mean_success"] < 0.5:
        return "SAC does not learn the task at this budget"
    success = rsp["mean_success"] >= max(0.8 * r["mean_success"], 0.5)
    if math.isnan(r["successful_impact"]):
        return (
            "more successful than r, which never succeeds; impacts not comparable"
            if success
            else "neither variant succeeds often enough to compare impacts"
        )
    impact = rsp["successful_impact"] <= 0.75 * r["successful_impact"]
    words = (
        "gentleness transfers"
        if success and impact
        else "gentler but less successful"
        if impact
        else "not gentler"
    )
    if task == "fragile" and rsp["mean_success"] >= r["mean_success"] + 0.3:
        words += "; helps on the fragile block"
    return words
