"""The commands: one module per ``gentlerl`` subcommand, each with ``main(argv, prog)``.

:mod:`~gentlerl.apps.train` (the hydra app, ``gentlerl-train``), :mod:`~gentlerl.apps.sweeps`,
:mod:`~gentlerl.apps.plot`, :mod:`~gentlerl.apps.claims`, :mod:`~gentlerl.apps.table`,
:mod:`~gentlerl.apps.evaluate`, :mod:`~gentlerl.apps.export`, :mod:`~gentlerl.apps.video`,
:mod:`~gentlerl.apps.calibration` and :mod:`~gentlerl.apps.forces`; with what they share:
:mod:`~gentlerl.apps.grid` (a sweep's grid points and how one runs, also used by the Ray
backend), :mod:`~gentlerl.apps.sweep_files` (sweep files read and checked),
:mod:`~gentlerl.apps.errors` (one-line refusals), :mod:`~gentlerl.apps.parsing` (the parser every
command starts from) and :mod:`~gentlerl.apps.outputs`. What the commands compute from runs is
:mod:`gentlerl.analysis`. Nothing here is imported by ``import gentlerl``.

Its public interface is the commands (``gentlerl COMMAND``, :data:`gentlerl.cli.COMMANDS`), not
Python names: ``__all__`` is empty.
"""

__all__: list[str] = []
