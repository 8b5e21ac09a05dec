"""Learning curves (paper Fig. 4): one panel per claim of :mod:`gentlerl.analysis.criteria`, at most
:data:`MAX_BANDS` variants per panel, every evaluation a point with its spread over seeds.

Evaluations happen every ``logging.eval_every_frames``; nothing is interpolated between them, so
each variant is a marker at each evaluated frame (the mean over the seeds evaluated there) with
an error bar from the min to the max over those seeds. Variants of one panel are shifted
sideways by a small fraction of the frame range so that their bars do not hide each other.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gentlerl.analysis.runs import EVAL_SUCCESS, PRIMARY_LAM2, Run, Series, group_runs  # noqa: E402

MAX_BANDS = 4
#: (title, variants, every lambda'_2): the claims' contrasts. ``r+rf+rsp`` at every lambda'_2 in
#: claim 5's panel, at the task's :data:`~gentlerl.analysis.runs.PRIMARY_LAM2` in claim 6's (every
#: lambda'_2 where the primary one was not run).
CLAIM_PANELS = (
    ("claim 4: the penalty alone", ("r", "r+rf", "r+rf+rs"), False),
    ("claim 5: penalty surprise vs task only", ("r", "r+rf+rsp"), True),
    ("claim 6: curiosity baselines", ("r", "r+icm", "r+rf+rsp"), False),
)
#: Sideways shift between the variants of a panel, as a fraction of its frame range.
DODGE = 0.012

Panel = tuple[str, list[tuple]]


def _chunks(fixed: list, varying: list, size: int) -> list[list]:
    """``fixed`` plus consecutive pieces of ``varying``, each list at most ``size`` long."""
    room = max(size - len(fixed), 1)
    pieces = [varying[i : i + room] for i in range(0, len(varying), room)] or [[]]
    return [fixed + piece for piece in pieces]


def _even_pieces(items: list, size: int) -> list[list]:
    """``items`` in the fewest consecutive pieces of at most ``size``, as even as possible."""
    if not items:
        return []
    count = -(-len(items) // size)
    return [[items[i] for i in piece] for piece in np.array_split(np.arange(len(items)), count)]


def _claim_groups(
    groups: dict[tuple, list[Run]], keys: list, variants: tuple, every_lam: bool
) -> list:
    """The group keys of one claim panel: its variants, rsp ones at the primary lambda'_2."""
    chosen = [k for k in keys if groups[k][0].variant in variants]
    rsp = [k for k in chosen if groups[k][0].lam2 is not None]
    primary = [k for k in rsp if groups[k][0].lam2 == PRIMARY_LAM2.get(k[0])]
    keep = rsp if every_lam or not primary else primary
    return [k for k in chosen if k not in rsp or k in keep]


def learning_curve_panels(groups: dict[tuple, list[Run]], max_bands: int = MAX_BANDS) -> list:
    """``[(title, group keys)]``: per task, one panel per claim of :data:`CLAIM_PANELS` that
    compares at least two of the variants present (and is not contained in an earlier panel),
    then the variants no panel showed, split evenly into panels; never more than ``max_bands``
    groups in a panel (a claim with more is split, its fixed variants repeated)."""
    panels: list[Panel] = []
    for task in sorted({key[0] for key in groups}, key=str):
        keys = [key for key in groups if key[0] == task]
        shown: set = set()
        for title, variants, every_lam in CLAIM_PANELS:
            chosen = _claim_groups(groups, keys, variants, every_lam)
            if len(chosen) < 2 or any(set(chosen) <= set(p) for _, p in panels):
                continue
            fixed = [k for k in chosen if groups[k][0].lam2 is None]
            varying = [k for k in chosen if k not in fixed]
            panels += [(f"{task}: {title}", c) for c in _chunks(fixed, varying, max_bands)]
            shown.update(chosen)
        rest = [k for k in keys if k not in shown]
        label = "variants" if len(rest) == len(keys) else "other variants"
        panels += [(f"{task}: {label}", piece) for piece in _even_pieces(rest, max_bands)]
    return panels


def eval_points(series: Sequence[Series]) -> tuple[np.ndarray, ...]:
    """Every frame at which any seed evaluated, with the mean, min and max over those seeds.

    Evaluations are points, not a curve: nothing is interpolated, so a logged 1.0 at 15k frames
    and 0.0 at 20k frames stay 1.0 and 0.0 (the mean at a frame uses the seeds evaluated there).
    """
    by_frame: dict[float, list[float]] = defaultdict(list)
    for frames, values in series:
        for f, v in zip(frames.tolist(), values.tolist(), strict=True):
            by_frame[f].append(v)
    frames = sorted(by_frame)
    stats = np.array([(np.mean(v), np.min(v), np.max(v)) for v in map(by_frame.get, frames)])
    stats = stats.reshape(len(frames), 3)
    return np.array(frames, dtype=float), stats[:, 0], stats[:, 1], stats[:, 2]


def seeds_label(n: int) -> str:
    """``"1 seed"``, ``"3 seeds"``."""
    return f"{n} seed" if n == 1 else f"{n} seeds"


def distinct_metrics(runs: Sequence[Run], metrics: Sequence[tuple[str, str]]) -> list:
    """``metrics`` without those that repeat an earlier one's values in every run.

    On the touch task the evaluation return is the success rate (reward 1 on success, then the
    episode ends), so a second panel would repeat the first. A metric no run has a number for
    (success on an env without a success outcome, logged as NaN) is left out too.
    """
    kept: list[tuple[str, str]] = []
    for name, label in metrics:
        logged = [r for r in runs if name in r.scalars and np.isfinite(r.scalars[name][1]).any()]
        repeats = any(
            all(_same_series(r.scalars[name], r.scalars.get(other)) for r in logged)
            for other, _ in kept
        )
        if logged and not repeats:
            kept.append((name, label))
    return kept


def _same_series(a: Series, b: Series | None) -> bool:
    return (
        b is not None
        and a[0].shape == b[0].shape
        and bool(np.array_equal(a[0], b[0]) and np.allclose(a[1], b[1]))
    )


def _draw_panel(ax: plt.Axes, name: str, groups: dict[tuple, list[Run]], keys: list) -> None:
    """One metric of one panel: a marker per evaluated frame and variant, min-max bars."""
    points = [eval_points([r.scalars[name] for r in groups[k] if name in r.scalars]) for k in keys]
    frames = np.concatenate([p[0] for p in points])
    span = float(frames.max() - frames.min()) if len(frames) else 0.0
    for i, (key, (x, mean, low, high)) in enumerate(zip(keys, points, strict=True)):
        seeds = sum(name in r.scalars for r in groups[key])
        label = f"{key[1]} ({seeds_label(seeds)})"
        if not len(x):
            ax.plot([], [], marker="o", linestyle="none", label=f"{label}: not evaluated")
            continue
        shift = (i - (len(keys) - 1) / 2) * DODGE * span
        yerr = np.stack([mean - low, high - mean])
        ax.errorbar(
            x + shift, mean, yerr=yerr, fmt="o", markersize=4, capsize=2, elinewidth=1, label=label
        )


def learning_curves_figure(runs: Sequence[Run]) -> plt.Figure:
    """Evaluation metrics (rows: success rate, and return where it differs) vs env frames, one
    column per panel of :func:`learning_curve_panels`, each column's legend under it."""
    metrics = distinct_metrics(runs, [(EVAL_SUCCESS, "success rate"), ("eval/return", "return")])
    metrics = metrics or [(EVAL_SUCCESS, "success rate")]
    groups = group_runs(runs)
    panels = learning_curve_panels(groups)
    if EVAL_SUCCESS not in dict(metrics):  # not the paper's tasks: its contrasts, not its claims
        panels = [(re.sub(r": claim \d+:", ":", title), keys) for title, keys in panels]
    shape = (len(metrics), len(panels))
    fig, axes = plt.subplots(*shape, figsize=(4.8 * shape[1], 3.3 * shape[0] + 1), squeeze=False)
    for col, (title, keys) in enumerate(panels):
        for row, (name, ylabel) in enumerate(metrics):
            ax = axes[row, col]
            _draw_panel(ax, name, groups, keys)
            ax.set(xlabel="env frames", ylabel=f"eval {ylabel}")
            ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(5))
        axes[0, col].set_title(title, fontsize=9)
        bottom = axes[-1, col]
        # Below the axes, outside the data: mean over seeds as points, bars min-max over seeds.
        bottom.legend(
            loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7, frameon=False,
            title="mean over seeds, bars: min-max", title_fontsize=7,
        )  # fmt: skip
    return fig
