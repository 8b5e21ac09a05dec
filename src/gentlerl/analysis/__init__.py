"""Reading finished runs and what is drawn and judged from them.

- :mod:`~gentlerl.analysis.runs`: the run reader (:func:`~gentlerl.analysis.runs.load_run`,
  :func:`~gentlerl.analysis.runs.find_runs`, the paper's figure selections); it imports none of
  the modules below;
- :mod:`~gentlerl.analysis.curves` and :mod:`~gentlerl.analysis.summary`: learning curves and the
  summary table of a set of runs;
- :mod:`~gentlerl.analysis.figures`: the ``gentlerl plot`` command (figures and summary files);
- :mod:`~gentlerl.analysis.criteria`: the six claims' pre-registered criteria, a verdict each;
- :mod:`~gentlerl.analysis.claims`: the ``gentlerl claims`` command (the criteria judged on grids
  of runs).
"""
