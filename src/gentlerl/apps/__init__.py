"""The commands: one module per ``gentlerl`` subcommand, each with ``main(argv, prog)``.

:mod:`~gentlerl.apps.train` (the hydra app, ``gentlerl-train``), :mod:`~gentlerl.apps.sweeps`,
:mod:`~gentlerl.apps.evaluate`, :mod:`~gentlerl.apps.export`, :mod:`~gentlerl.apps.video` and
:mod:`~gentlerl.apps.calibration`; with what they share: :mod:`~gentlerl.apps.grid` (a sweep's
grid points and how one runs, also used by the Ray backend), :mod:`~gentlerl.apps.sweep_files`
(sweep files read and checked), :mod:`~gentlerl.apps.errors` (one-line refusals),
:mod:`~gentlerl.apps.parsing` (the parser every command starts from) and
:mod:`~gentlerl.apps.outputs`. ``gentlerl plot`` and ``gentlerl claims`` are in
:mod:`gentlerl.analysis`. Nothing here is imported by ``import gentlerl``.
"""
