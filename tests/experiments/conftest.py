"""The tests of the checkout's ``experiments/``: its root on ``sys.path`` so that they import
``experiments.<name>`` as the scripts do."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
