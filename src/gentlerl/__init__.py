"""gentlerl: gentle object manipulation with curiosity-driven deep RL, for TorchRL."""

import importlib.util
import sys

__version__ = "0.1.0"


def _record_missing_pandas() -> None:
    """Make tensordict's per-call probe for pandas a dictionary look-up.

    ``TensorDict.from_any``, which ``TensorDictModule`` runs on every output, calls
    ``importlib.util.find_spec("pandas")`` each time; without pandas installed that searches
    ``sys.path`` on every call (~70 µs, 6 % of a default training run, benchmarks/RESULTS.md).
    ``sys.modules["pandas"] = None`` is Python's record of a module that cannot be imported:
    ``find_spec`` then returns None at once and ``import pandas`` raises ``ImportError``, as
    it would anyway. Nothing changes where pandas is installed.
    """
    if "pandas" not in sys.modules and importlib.util.find_spec("pandas") is None:
        sys.modules["pandas"] = None


_record_missing_pandas()

# Before anything imports dm_control (a TorchRL DMControlEnv too): on a headless machine its
# default backend, GLFW, prints a GLFWError about the missing DISPLAY.
from gentlerl.opengl import configure_gl  # noqa: E402

configure_gl()
