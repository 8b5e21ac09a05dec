"""objectives.compile.compile_unavailable: ``None`` where ``torch.compile`` can run, otherwise the
reason, one per missing piece (dynamo, inductor's import, a C++ compiler)."""

import shutil
import sys

import pytest
import torch
import torch._inductor.cpp_builder

from gentlerl.objectives.compile import compile_unavailable


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
