"""The pre-registered tests of docs/log/GENTLEBENCH.md's Method III amendments, one function per rule.

The table they judge is :mod:`experiments.method3.table` (``python experiments/method3/table.py``): task ->
variant label -> a row with ``score`` (success on the hand, return off it, mean over seeds),
``median_score``, ``median_impact`` (N) and ``rsp_per_contact``.
"""

from __future__ import annotations

from collections.abc import Mapping

Rows = Mapping[str, Mapping[str, Mapping[str, float]]]

#: The Method III grid's rows per task, in table order (:mod:`experiments.method3.table`).
METHOD3_VARIANTS = ("r", "r+rf+rsp", "new", "baseline", "norm alone", "pid alone", "new, w0=1")
#: The foreign tasks' return tests: F1 on finger-turn_easy (first amendment), F2 on finger-spin
#: (fifth amendment, at the budget where ``r`` learns it).
FOREIGN_TESTS = {"finger-turn_easy": "F1", "finger-spin": "F2"}
#: The rows judged as a candidate new method (every test), and the single mechanisms (the hand's).
CANDIDATES = ("new", "new, w0=1")
MECHANISMS = ("norm alone", "pid alone")


def _test(holds: bool, numbers: str) -> str:
    return ("holds" if holds else "does not hold") + f" ({numbers})"


def method3_equal_impact(new: Mapping[str, float], baseline: Mapping[str, float]) -> str:
    """Test B: the new method's score (success or return) >= the baseline's when its median max
    impact is at most 1.25 x the baseline's; above that, "not at equal impact"."""
    numbers = f"{new['score']:.2f} at {new['median_impact']:.2f} N vs "
    numbers += f"{baseline['score']:.2f} at {baseline['median_impact']:.2f} N"
    if new["median_impact"] > 1.25 * baseline["median_impact"]:
        return f"not at equal impact ({numbers})"
    return _test(new["score"] >= baseline["score"], numbers)


def keeps_return_gently(new: Mapping[str, float], r: Mapping[str, float]) -> str:
    """Tests F1 / F2: the new method's median return >= 0.8 x ``r``'s at a median max impact
    <= 0.5 x ``r``'s."""
    return _test(
        new["median_score"] >= 0.8 * r["median_score"]
        and new["median_impact"] <= 0.5 * r["median_impact"],
        f"median return {new['median_score']:.1f} vs r {r['median_score']:.1f}, "
        f"{new['median_impact']:.1f} vs {r['median_impact']:.1f} N",
    )


def hand_tests(rows: Rows, label: str) -> dict[str, str]:
    """H1: touch, success >= 0.95 at a median max impact <= 3 N. H2: fragile, success >= 0.8."""
    named = "" if label == "new" else f", {label}"
    t, f = rows.get("touch", {}).get(label), rows.get("fragile", {}).get(label)
    out = {}
    if t:
        numbers = f"success {t['score']:.2f} at {t['median_impact']:.2f} N"
        out["H1 touch" + named] = _test(t["score"] >= 0.95 and t["median_impact"] <= 3, numbers)
    if f:
        out["H2 fragile" + named] = _test(f["score"] >= 0.8, f"{f['score']:.2f}")
    return out


def foreign_tests(rows: Rows, label: str) -> dict[str, str]:
    """F1 / F2 (:func:`keeps_return_gently`) per foreign task; B (:func:`method3_equal_impact`)
    per task with a baseline row; N: r^sp per contact step on each foreign task within 2x of its
    value on touch."""
    named = "" if label == "new" else f", {label}"
    out = {}
    for task, test in FOREIGN_TESTS.items():
        new, r = rows.get(task, {}).get(label), rows.get(task, {}).get("r")
        if new and r:
            out[f"{test} {task}{named}"] = keeps_return_gently(new, r)
    for task, labels in rows.items():
        if label in labels and "baseline" in labels:
            out[f"B {task}{named}"] = method3_equal_impact(labels[label], labels["baseline"])
    touch = rows.get("touch", {}).get(label)
    for task in FOREIGN_TESTS:
        new = rows.get(task, {}).get(label)
        if new and touch:
            rsp = touch["rsp_per_contact"]
            ratio = new["rsp_per_contact"] / rsp if rsp else float("nan")
            numbers = f"{task} / touch = {ratio:.2f}"
            out[f"N {task}{named}"] = _test(0.5 <= ratio <= 2.0, numbers)
    return out


def method3_verdicts(rows: Rows) -> dict[str, str]:
    """Every Method III test the rows allow (a test whose rows are missing is absent): the hand's
    H1, H2 for each candidate and each mechanism alone (third amendment), the foreign and
    baseline tests F1, F2, B, N for each candidate (:data:`CANDIDATES`)."""
    out = {}
    for label in (*CANDIDATES, *MECHANISMS):
        out.update(hand_tests(rows, label))
        if label in CANDIDATES:
            out.update(foreign_tests(rows, label))
    return out
