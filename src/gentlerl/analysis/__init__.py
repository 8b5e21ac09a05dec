"""Reading finished runs and what is drawn and judged from them.

- :mod:`~gentlerl.analysis.runs`: the run reader (:func:`~gentlerl.analysis.runs.load_run`,
  :func:`~gentlerl.analysis.runs.find_runs`, the paper's figure selections); it imports none of
  the modules below;
- :mod:`~gentlerl.analysis.curves` and :mod:`~gentlerl.analysis.summary`: learning curves and the
  summary table of a set of runs;
- :mod:`~gentlerl.analysis.figures`: the figures and summary files of ``gentlerl plot``;
- :mod:`~gentlerl.analysis.criteria`: the paper's six claims as pre-registered criteria, one
  function per claim;
- :mod:`~gentlerl.analysis.claims`: the six claims judged on grids of runs (``gentlerl claims``).

The project's own experiments (the SAC grid, GentleBench, Method III) and their tables are not part
of the library: they live in a checkout's ``experiments/`` folder.

The commands themselves are in :mod:`gentlerl.apps`. The names below, the run reader and the
summary and figures of ``gentlerl plot``, are the package's public API (imported on first use,
:mod:`gentlerl.lazy`); the pre-registered grids' criteria and tables are not part of it.
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.analysis.figures": ("write_figures",),
        "gentlerl.analysis.runs": ("Run", "find_runs", "group_runs", "load_run"),
        "gentlerl.analysis.summary": ("format_table", "summary_markdown", "summary_table"),
    },
)
