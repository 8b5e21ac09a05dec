"""Deprecated: ``python recipes/train.py ARGS`` runs ``gentlerl train ARGS``; removed in 0.3.0.

This second entry point of the hydra app (:mod:`gentlerl.apps.train`) was removed in 0.2.0
without a deprecation; until 0.3.0 it warns and runs ``gentlerl train`` with the same arguments
(``task=touch variant=r+rf+rsp seed=0``, ``--help``, ``-m`` sweeps).
"""

import sys

from gentlerl.cli import main
from gentlerl.deprecation import warn_deprecated

if __name__ == "__main__":
    warn_deprecated("python recipes/train.py", "gentlerl train", stacklevel=2)
    sys.exit(main(["train", *sys.argv[1:]]))
