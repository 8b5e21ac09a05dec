"""objectives.launch.compile_unavailable: ``None`` where ``torch.compile`` can run, otherwise the
reason, one per missing piece (dynamo, inductor's import, a C++ compiler); and what
``compile_step`` does with it (the eager step and a warning at the caller) and with ``cudagraphs``
(the step in a ``CudaGraphModule`` with its warmup; a recording stand-in here, so no CUDA and none
of the real module's process-wide settings)."""

import shutil
import sys

import pytest
import torch
import torch._inductor.cpp_builder

from gentlerl.objectives import launch as compile_module
from gentlerl.objectives.launch import EagerOnBuildFailure, compile_step, compile_unavailable


@pytest.mark.skipif(
    not torch._dynamo.is_dynamo_supported() or shutil.which("g++") is None,
    reason="needs dynamo and a C++ compiler",
)
def test_none_where_dynamo_and_a_compiler_exist():
    assert compile_unavailable() is None


def test_the_reason_when_dynamo_is_unsupported(monkeypatch):
    monkeypatch.setattr(torch._dynamo, "is_dynamo_supported", lambda: False)
    assert compile_unavailable() == "torch.compile does not support this Python / platform"


def test_the_reason_when_there_is_no_compiler(monkeypatch):
    class NoCompilerError(RuntimeError):
        pass

    def no_compiler():
        raise NoCompilerError("no g++ here")

    monkeypatch.setattr(torch._dynamo, "is_dynamo_supported", lambda: True)
    monkeypatch.setattr(torch._inductor.cpp_builder, "get_cpp_compiler", no_compiler)
    assert compile_unavailable() == "no C++ compiler for inductor (NoCompilerError)"


def test_the_reason_when_inductor_does_not_import(monkeypatch):
    monkeypatch.setattr(torch._dynamo, "is_dynamo_supported", lambda: True)
    monkeypatch.delattr(torch._inductor, "cpp_builder")
    monkeypatch.setitem(sys.modules, "torch._inductor.cpp_builder", None)
    reason = compile_unavailable()
    assert reason.startswith("torch's inductor backend does not import (")
    assert "torch._inductor.cpp_builder" in reason and reason.endswith(")")


def test_the_patches_are_undone():
    """After the tests above: the real checks are back."""
    assert torch._inductor.cpp_builder.get_cpp_compiler.__module__ == "torch._inductor.cpp_builder"
    assert sys.modules["torch._inductor.cpp_builder"] is torch._inductor.cpp_builder


def test_compile_step_without_dynamo_is_the_eager_step_and_warns_the_caller(monkeypatch):
    monkeypatch.setattr(torch._dynamo, "is_dynamo_supported", lambda: False)

    def step(x):
        return x + 1

    with pytest.warns(UserWarning) as record:
        out = compile_step(step, compile=True, name="the dynamics model")
    assert out is step
    (warning,) = [w for w in record if "learner.compile" in str(w.message)]
    assert str(warning.message) == (
        "learner.compile: torch.compile does not support this Python / platform; "
        "the dynamics model runs eagerly"
    )
    # stacklevel: the warning points at the caller, not at compile.py
    assert not warning.filename.endswith("compile.py")


def test_a_build_failure_warns_the_caller_of_the_step():
    def failing(x):
        raise torch._dynamo.exc.BackendCompilerFailed(failing, RuntimeError("no"), None)

    step = EagerOnBuildFailure(lambda x: x + 1, failing)
    with pytest.warns(UserWarning, match="inductor failed to build") as record:
        assert step(1) == 2
    assert not record[0].filename.endswith("compile.py")


class _RecordingCudaGraphModule:
    def __init__(self, module, **kwargs):
        self.module, self.kwargs = module, kwargs


@pytest.mark.parametrize("warmup", [None, 2])
def test_cudagraphs_wraps_the_step_with_its_warmup(monkeypatch, warmup):
    monkeypatch.setattr(compile_module, "CudaGraphModule", _RecordingCudaGraphModule)

    def step(x):
        return x

    if warmup is None:
        out = compile_step(step, cudagraphs=True)
    else:
        out = compile_step(step, cudagraphs=True, warmup=warmup)
    assert isinstance(out, _RecordingCudaGraphModule) and out.module is step
    assert out.kwargs == {"in_keys": [], "out_keys": [], "warmup": 5 if warmup is None else 2}
    assert compile_step(step) is step  # neither: the step itself
