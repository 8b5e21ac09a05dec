"""The SAC grid's pre-registered verdict (docs/log/SAC.md), one per task."""

from __future__ import annotations

import math
from collections.abc import Mapping


def sac_verdict(task: str, r: Mapping[str, float], rsp: Mapping[str, float]) -> str:
    """The verdict on one task from the ``r`` and ``r+rf+rsp`` rows of SAC.

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
