"""Moved out of the library in 0.2.0: the SAC grid's and GentleBench's tables are experiments of
the project, run from a checkout (``python experiments/sac_grid/table.py RUNS_DIR``,
``python experiments/gentlebench/table.py RUNS_DIR``)."""

raise ImportError(
    "gentlerl.analysis.grid_tables moved out of the library in 0.2.0: run python "
    "experiments/sac_grid/table.py or python experiments/gentlebench/table.py from a checkout"
)
