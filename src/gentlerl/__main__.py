"""``python -m gentlerl`` is the ``gentlerl`` command."""

from gentlerl.cli import main

raise SystemExit(main())
