"""The summary table of ``gentlerl plot`` (``summary.csv`` / ``summary.md``): per variant, the
numbers the claims' criteria (:mod:`gentlerl.analysis.criteria`) judge, each from the selection it names.

- ``final_*``: the final policy (:func:`gentlerl.analysis.runs.final_policy_episodes`;
  ``final_source`` says which episodes: ``evaluate`` = the 20 episodes of ``gentlerl evaluate``,
  ``in-loop`` = the run's last in-loop evaluation, ``none``). ``final_successful_*``: max impact of
  its *successful* rollouts (paper Fig. 5, :func:`gentlerl.analysis.runs.successful_final_impacts`).
  ``final_return``, ``final_median_impact``, ``final_p90_impact``: mean task return and max impact
  (N) of every final-policy episode, what an env without success (an external env such as
  dm_control's finger) is judged by.
- ``*after_switch``: training rollouts after the intrinsic rewards switch on (paper Fig. 3,
  :func:`gentlerl.analysis.runs.after_intrinsic_start`); impact columns over the touching ones (max
  impact > 0), in N.
- ``mean_eval_success``, ``seeds_reaching_0.8``, ``first_0.8_frames``: the in-loop evaluations.
- ``seeds_gentle``, ``gentle_frames``, ``gentle_wall_s``: the time to a gentle policy
  (:func:`time_to_gentle`), the mean over the seeds that reached one; ``*held_gentle*``: the same
  for the first evaluation from which the run stayed gentle.
- ``rsp_fade``: whether the penalty surprise fades (:func:`fade_ratio`), the median over seeds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gentlerl.analysis.runs import (
    EVAL_SUCCESS,
    Run,
    after_intrinsic_start,
    after_switch,
    final_policy_episodes,
    final_sources,
    group_runs,
    in_loop_episodes,
    intrinsic_start,
    successful_final_impacts,
)

NAN = float("nan")


def _first_success(run: Run, threshold: float = 0.8) -> float:
    frames, success = run.scalars.get(EVAL_SUCCESS, (np.zeros(0), np.zeros(0)))
    hits = frames[success >= threshold]
    return float(hits[0]) if len(hits) else NAN


#: A gentle policy (the throughput headline): an in-loop evaluation whose episodes succeed at
#: least this often ...
GENTLE_SUCCESS = 0.8
#: ... at a median per-episode max impact of at most this many newtons.
GENTLE_IMPACT_N = 3.0


def time_to_gentle(
    run: Run,
    success: float = GENTLE_SUCCESS,
    impact_n: float = GENTLE_IMPACT_N,
    *,
    held: bool = False,
) -> tuple[float, float]:
    """``(frames, wall seconds)`` at the run's first in-loop evaluation whose episodes succeed
    at a mean rate >= ``success`` with a median per-episode max impact <= ``impact_n`` newtons
    (the env's ``env.force_scale`` undone); ``(nan, nan)`` if none did. With ``held``, the first
    evaluation from which every later one is gentle too (an untrained actor that touches softly
    by chance at the first evaluation is gentle *first*, not *held*).

    The seconds are the run's training wall clock at that frame (``train/wall_s``: set-up
    excluded, the time before a resume included); nan for a run logged before it existed. A
    task without a success outcome (an external env) never reaches a gentle policy.

    Example: evaluations at 5k (success 1.0, median 2.1 N), 10k (0.0) and 15k (0.8, 2.5 N) ->
    5k frames first, 15k held.
    """
    rows = in_loop_episodes(run)
    newtons = float(run.setting("env", "force_scale", 1.0) or 1.0)
    frames = np.unique(rows["frames"]) if len(rows) else np.zeros(0)
    gentle = [
        rows["success"][rows["frames"] == f].mean() >= success
        and np.median(rows["max_impact"][rows["frames"] == f]) / newtons <= impact_n
        for f in frames
    ]
    if held:  # the first of the final unbroken run of gentle evaluations
        last_fail = max((i for i, ok in enumerate(gentle) if not ok), default=-1)
        gentle = [i > last_fail for i in range(len(gentle))]
    if not any(gentle):
        return NAN, NAN
    frame = float(frames[gentle.index(True)])
    wall = run.scalars.get("train/wall_s")
    seconds = float(np.interp(frame, *wall)) if wall is not None and len(wall[0]) else NAN
    return frame, seconds


#: The logged mean r^sp per contact step (recomputed at sampling), which :func:`fade_ratio` reads.
RSP_PER_CONTACT = "train/penalty_surprise_per_contact_step"


def fade_ratio(run: Run, name: str = RSP_PER_CONTACT, window: float = 5000.0) -> float:
    """How much of a reward is left at the end: the mean of the scalar ``name`` over the run's
    last ``window`` frames over its mean over the first ``window`` frames after the intrinsic
    rewards switch on (:func:`~gentlerl.analysis.runs.intrinsic_start`); nan without data or
    with a first mean of 0. 0.5 means it halved. Example: 2.0 for 5k frames, later 1.0 -> 0.5.
    """
    frames, values = run.scalars.get(name, (np.zeros(0), np.zeros(0)))
    on = frames > intrinsic_start(run)
    frames, values = frames[on], values[on]
    if not len(frames):
        return NAN
    first = values[frames <= frames[0] + window]
    last = values[frames > frames[-1] - window]
    return float(last.mean() / first.mean()) if first.mean() != 0 else NAN


def _share(part: int, whole: int) -> float:
    return part / whole if whole else NAN  # no rollouts: undefined, not 0


def _finite(values: np.ndarray) -> np.ndarray:
    return values[np.isfinite(values)]


def _mean(values: np.ndarray) -> float:
    return float(np.mean(values)) if len(values) else NAN


def _median(values: np.ndarray) -> float:
    return float(np.median(values)) if len(values) else NAN


def _p90(values: np.ndarray) -> float:
    return float(np.percentile(values, 90)) if len(values) else NAN


def final_policy_columns(group: Sequence[Run]) -> dict[str, object]:
    """The ``final_*`` columns of one variant's runs (see the module docstring)."""
    episodes = [rows for rows, _ in map(final_policy_episodes, group)]
    rates = [rows["success"].mean() for rows in episodes if len(rows)]
    successful = successful_final_impacts(group)
    return {
        "final_success": float(np.mean(rates)) if rates else NAN,
        "final_source": final_sources(group),
        "final_episodes": sum(map(len, episodes)),
        "final_successful": len(successful),
        "final_successful_median_impact": _median(successful),
        "final_successful_p90_impact": _p90(successful),
        **_all_final_columns(episodes),
    }


def _all_final_columns(episodes: Sequence[np.ndarray]) -> dict[str, float]:
    # numpy.genfromtxt renames the column "return", a python keyword, to "return_"
    rows = [r for r in episodes if len(r) and "return_" in (r.dtype.names or ())]
    impacts = np.concatenate([r["max_impact"] for r in rows]) if rows else np.zeros(0)
    returns = np.concatenate([r["return_"] for r in rows]) if rows else np.zeros(0)
    return {
        "final_return": float(returns.mean()) if len(returns) else NAN,
        "final_median_impact": _median(impacts),
        "final_p90_impact": _p90(impacts),
    }


def after_switch_columns(group: Sequence[Run]) -> dict[str, object]:
    """The ``*after_switch`` columns of one variant's runs (see the module docstring)."""
    every = after_intrinsic_start(group, with_zeros=True)
    touching = every[every > 0]
    broken = np.concatenate([after_switch(r, "episode/broken") for r in group])
    in_5_15 = int(((touching >= 5) & (touching <= 15)).sum())
    return {
        "switch_frames": float(np.mean([intrinsic_start(r) for r in group])),
        "rollouts_after_switch": len(every),
        "touching_share_after_switch": _share(len(touching), len(every)),
        "median_impact_after_switch": _median(touching),
        "p90_impact_after_switch": _p90(touching),
        "share_under_5N_after_switch": _share(int((touching < 5).sum()), len(touching)),
        "share_5_15N_after_switch": _share(in_5_15, len(touching)),
        "broken_share_after_switch": _share(int(broken.sum()), len(broken)),
    }


def summary_table(runs: Sequence[Run]) -> list[dict[str, object]]:
    """One row per group of runs that differ only by seed (columns: the module docstring);
    a column without data reads ``nan``."""
    rows = []
    for (task, label), group in group_runs(runs).items():
        evals = [r.scalars[EVAL_SUCCESS][1] for r in group if EVAL_SUCCESS in r.scalars]
        first = np.array([_first_success(r) for r in group])
        reached = first[~np.isnan(first)]
        gentle, held = (
            _reached([time_to_gentle(r, held=h) for r in group]) for h in (False, True)
        )  # fmt: skip
        rows.append(
            {
                "task": task,
                "variant": label,
                "seeds": len(group),
                **final_policy_columns(group),
                "mean_eval_success": float(np.mean([e.mean() for e in evals])) if evals else NAN,
                "seeds_reaching_0.8": len(reached),
                "first_0.8_frames": float(reached.mean()) if len(reached) else NAN,
                "seeds_gentle": len(gentle),
                "gentle_frames": float(gentle[:, 0].mean()) if len(gentle) else NAN,
                "gentle_wall_s": _mean(_finite(gentle[:, 1])),
                "seeds_held_gentle": len(held),
                "held_gentle_frames": float(held[:, 0].mean()) if len(held) else NAN,
                "held_gentle_wall_s": _mean(_finite(held[:, 1])),
                "rsp_fade": _median(_finite(np.array([fade_ratio(r) for r in group]))),
                **after_switch_columns(group),
            }
        )
    return rows


def _reached(times: list[tuple[float, float]]) -> np.ndarray:
    """``[n, 2]`` (frames, seconds) of the seeds whose :func:`time_to_gentle` is not nan."""
    times_ = np.array(times, dtype=float).reshape(-1, 2)
    return times_[~np.isnan(times_[:, 0])]


def _cell(value: object) -> str:
    """One markdown cell: floats to 2 decimals; a name's line breaks and pipes escaped (a run
    folder named ``a\n| x |`` stays one cell, not an injected row)."""
    if isinstance(value, float):
        return f"{value:.2f}"
    text = str(value).replace("\\", "\\\\").replace("|", "\\|")
    return " ".join(text.splitlines())


def _no_data(value: object) -> bool:
    return isinstance(value, float) and np.isnan(value)


def format_table(rows: Sequence[dict[str, object]]) -> str:
    """``rows`` of :func:`summary_table` as a markdown table (floats to 2 decimals), without the
    columns no row has data for (an external env's success and broken rates)."""
    names = [n for n in rows[0] if not all(_no_data(row[n]) for row in rows)]
    lines = ["| " + " | ".join(names) + " |", "|" + " --- |" * len(names)]
    lines += ["| " + " | ".join(_cell(row[n]) for n in names) + " |" for row in rows]
    return "\n".join(lines)


def summary_markdown(rows: Sequence[dict[str, object]]) -> str:
    """``summary.md``: what each column selects (the module docstring), then the table."""
    return f"{__doc__.strip()}\n\n{format_table(rows)}\n"
