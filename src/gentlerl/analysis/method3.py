"""Moved out of the library in 0.2.0: the Method III grid's table is an experiment of the project,
run from a checkout (``python experiments/method3/table.py RUNS_DIR``)."""

raise ImportError(
    "gentlerl.analysis.method3 moved out of the library in 0.2.0: run python "
    "experiments/method3/table.py from a checkout"
)
