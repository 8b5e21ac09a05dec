"""Launching an update step as TorchRL's sota-implementations do: ``torch.compile`` and / or one
CUDA graph, falling back to the eager step where the machine cannot build it. The D4PG learner
and every reward model's step go through :func:`compile_step`."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any, TypeVar, cast

import torch
from tensordict.nn import CudaGraphModule

Step = TypeVar("Step", bound=Callable[..., Any])


def compile_step(
    step: Step,
    *,
    compile: bool = False,
    cudagraphs: bool = False,
    warmup: int = 5,
    name: str = "the learner",
) -> Step:
    """``step`` through ``torch.compile`` and / or a CUDA graph, as TorchRL's sota-implementations.

    Without a working ``torch.compile`` (no C++ compiler for inductor on CPU, an unsupported
    Python) ``compile`` falls back to the eager step with a warning that says why; so does a
    compiled step whose build fails when it is first called (:class:`EagerOnBuildFailure`).
    ``cudagraphs`` wraps the step in ``tensordict.nn.CudaGraphModule`` (its first ``warmup`` calls
    run eagerly, then one graph is replayed; inputs are copied in, outputs cloned out).
    """
    if compile:
        reason = compile_unavailable()
        if reason is None:
            # tensordict reads a dynamo setting that torch 2.13 deprecates, once per trace.
            warnings.filterwarnings(
                "ignore", "torch._dynamo.config.inline_inbuilt_nn_modules", FutureWarning
            )
            step = cast(Step, EagerOnBuildFailure(step, torch.compile(step)))
        else:
            warnings.warn(f"learner.compile: {reason}; {name} runs eagerly", stacklevel=2)
    if cudagraphs:
        step = CudaGraphModule(step, in_keys=[], out_keys=[], warmup=warmup)
    return step


class EagerOnBuildFailure:
    """``compiled`` until inductor fails to build it (``BackendCompilerFailed``, raised before
    the step runs, so nothing was half-done), then ``eager`` with a warning naming the failure.

    Example: a stale inductor cache built for another CPU capability fails to compile its C++
    ("'at::vec' has not been declared"); the run goes on eagerly instead of stopping.
    """

    def __init__(self, eager: Callable[..., Any], compiled: Callable[..., Any]) -> None:
        self.eager, self.compiled = eager, compiled

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if self.compiled is None:
            return self.eager(*args, **kwargs)
        try:
            return self.compiled(*args, **kwargs)
        except torch._dynamo.exc.BackendCompilerFailed as err:
            inner = getattr(err, "inner_exception", err)
            first = f"{type(inner).__name__}: {(str(inner).strip() or '-').splitlines()[0]}"
            warnings.warn(
                f"learner.compile: inductor failed to build the update ({first[:200]}); the "
                "learner runs eagerly from here",
                stacklevel=2,
            )
            self.compiled = None
            return self.eager(*args, **kwargs)


def compile_unavailable() -> str | None:
    """Why ``torch.compile`` cannot run here, or ``None`` when it can."""
    if not torch._dynamo.is_dynamo_supported():
        return "torch.compile does not support this Python / platform"
    try:
        from torch._inductor import cpp_builder
    except ImportError as err:
        return f"torch's inductor backend does not import ({err})"
    try:
        cpp_builder.get_cpp_compiler()
    except Exception as err:  # inductor's own check raises its InvalidCxxCompiler
        return f"no C++ compiler for inductor ({type(err).__name__})"
    return None
