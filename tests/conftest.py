"""Test-session settings and shared fixtures."""

import atexit
import os
import shutil
import tempfile

import pytest
import torch

# A compile cache of this session's own: inductor's on-disk cache key ignores
# ATEN_CPU_CAPABILITY, so a suite run with ATEN_CPU_CAPABILITY=default (CI's second pass) after an
# AVX2 run loaded AVX2 kernels and failed to build them ("'at::vec' has not been declared").
if "TORCHINDUCTOR_CACHE_DIR" not in os.environ:
    os.environ["TORCHINDUCTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="gentlerl-inductor-")
    atexit.register(shutil.rmtree, os.environ["TORCHINDUCTOR_CACHE_DIR"], ignore_errors=True)

# One thread: on the 2-core CI machine, two torch threads contend with the env and with
# collector / ParallelEnv worker processes and made the model-training tests ~20x slower.
torch.set_num_threads(1)

#: Per-test limit of ``@pytest.mark.slow`` learning runs (the default, in pyproject.toml, is 5 min).
SLOW_TIMEOUT_S = 3600


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))


@pytest.fixture
def hand_env():
    """``gentlerl.envs.make_env`` whose envs are all closed when the test ends, pass or fail.

    Closing frees each env's physics and GL context at a known point instead of inside a later
    test's garbage collection.
    """
    from gentlerl.envs import make_env

    yield from closing_builder(make_env)


@pytest.fixture
def driver_env():
    """``DriverHandEnv`` whose envs (and drivers) are closed when the test ends."""
    from gentlerl.envs import DriverHandEnv

    yield from closing_builder(DriverHandEnv)


def closing_builder(factory):
    """Yields ``build(*args, **kwargs) -> factory(...)``, then closes every env it built."""
    made = []

    def build(*args, **kwargs):
        made.append(factory(*args, **kwargs))
        return made[-1]

    yield build
    for env in made:
        if not env.is_closed:
            env.close()
