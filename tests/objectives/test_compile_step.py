"""compile_step's choices and EagerOnBuildFailure's warning, without building anything.

torch.compile and the machine's compiler check are replaced by stand-ins (monkeypatch), so these
tests take milliseconds; the compiled learner itself is tested in test_compile.py.
"""

import warnings

import pytest
import torch

import gentlerl.objectives.launch as compile_module
from gentlerl.objectives.launch import EagerOnBuildFailure, compile_step


def _step(x, scale=1):
    return x * scale


def _fake_compile(fn):
    def compiled(*args, **kwargs):
        return ("compiled", fn(*args, **kwargs))

    return compiled


def test_by_default_the_step_is_returned_as_it_is():
    assert compile_step(_step) is _step


def test_without_a_compiler_the_step_runs_eagerly_and_the_warning_names_reason_and_step(
    monkeypatch,
):
    monkeypatch.setattr(compile_module, "compile_unavailable", lambda: "no C++ compiler (X)")
    with pytest.warns(UserWarning) as record:
        step = compile_step(_step, compile=True, name="the penalty model")
    assert step is _step
    assert [str(w.message) for w in record] == [
        "learner.compile: no C++ compiler (X); the penalty model runs eagerly"
    ]
    assert not record[0].filename.endswith("compile.py")  # it points at a caller
    with pytest.warns(UserWarning, match=r"; the learner runs eagerly$"):  # the default name
        compile_step(_step, compile=True)


def test_with_a_compiler_the_step_is_compiled_with_its_eager_fallback(monkeypatch):
    monkeypatch.setattr(compile_module, "compile_unavailable", lambda: None)
    monkeypatch.setattr(torch, "compile", _fake_compile)
    step = compile_step(_step, compile=True)
    assert isinstance(step, EagerOnBuildFailure) and step.eager is _step
    assert step(2, scale=3) == ("compiled", 6)  # keyword arguments reach the compiled step


def test_compiling_silences_only_tensordicts_deprecated_dynamo_setting(monkeypatch):
    monkeypatch.setattr(compile_module, "compile_unavailable", lambda: None)
    monkeypatch.setattr(torch, "compile", _fake_compile)
    setting = "torch._dynamo.config.inline_inbuilt_nn_modules is deprecated"
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        compile_step(_step, compile=True)
        warnings.warn(setting, FutureWarning, stacklevel=1)  # silenced
        warnings.warn("another deprecation", FutureWarning, stacklevel=1)
        warnings.warn(setting, UserWarning, stacklevel=1)  # same words, other category: kept
    assert [(w.category, str(w.message)) for w in record] == [
        (FutureWarning, "another deprecation"),
        (UserWarning, setting),
    ]


def _failing(*args, **kwargs):
    raise torch._dynamo.exc.BackendCompilerFailed(_failing, RuntimeError("x" * 300), None)


def test_the_build_failure_warning_holds_the_first_200_characters_of_the_error():
    # "RuntimeError: " is 14 characters: 186 of the 300 x's are left.
    step = EagerOnBuildFailure(_step, _failing)
    with pytest.warns(UserWarning) as record:
        assert step(2, scale=5) == 10  # the eager step, keyword arguments included
    assert str(record[0].message) == (
        f"learner.compile: inductor failed to build the update (RuntimeError: {'x' * 186}); "
        "the learner runs eagerly from here"
    )
    assert not record[0].filename.endswith("compile.py")  # it points at a caller
    assert step(3, scale=2) == 6 and step.compiled is None


def test_a_build_failure_without_a_message_or_an_inner_error_still_names_itself():
    def empty(*args):
        raise torch._dynamo.exc.BackendCompilerFailed(empty, RuntimeError(""), None)

    with pytest.warns(UserWarning, match=r"update \(RuntimeError: -\); the"):
        EagerOnBuildFailure(_step, empty)(1)

    def bare(*args):  # an error whose inner_exception is missing names itself
        err = torch._dynamo.exc.BackendCompilerFailed.__new__(
            torch._dynamo.exc.BackendCompilerFailed
        )
        Exception.__init__(err, "no backend")
        raise err

    with pytest.warns(UserWarning, match=r"update \(BackendCompilerFailed: no backend\); the"):
        EagerOnBuildFailure(_step, bare)(1)
