"""GentleBench's pre-registered verdict (docs/log/GENTLEBENCH.md), one per task and variant."""

from __future__ import annotations

from collections.abc import Mapping

#: Below this median return ``r`` has not learned its task (2 % of dm_control's 1000).
GENTLEBENCH_R_LEARNS = 20.0


def gentlebench_verdict(
    r: Mapping[str, float], other: Mapping[str, float], budget: str = "30k"
) -> str:
    """The label of one variant against ``r`` on the same task.

    Each row holds ``median_return`` (median over seeds of the per-run mean return) and
    ``median_impact`` (median per-episode max impact, N). *keeps the return*: ``other``'s median
    return >= 0.8 x ``r``'s; *gentler*: its median impact <= 0.5 x ``r``'s. Both: "gentle and as
    good"; only *gentler*: "gentle but worse"; only *keeps*: "no gentleness gain"; else "neither".
    When ``r``'s median return is below :data:`GENTLEBENCH_R_LEARNS` the return test says nothing:
    "not judged: r does not learn at <budget>" (with "; gentler" when that test holds).
    """
    gentler = other["median_impact"] <= 0.5 * r["median_impact"]
    if r["median_return"] < GENTLEBENCH_R_LEARNS:
        return f"not judged: r does not learn at {budget}" + ("; gentler" if gentler else "")
    keeps = other["median_return"] >= 0.8 * r["median_return"]
    return {
        (True, True): "gentle and as good",
        (False, True): "gentle but worse",
        (True, False): "no gentleness gain",
        (False, False): "neither",
    }[(keeps, gentler)]
