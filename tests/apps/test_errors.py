"""One-line errors: an unexpected error names its type and the debug switch; a masked Ctrl-C still
reads as interrupted."""

from __future__ import annotations


def test_an_unexpected_error_names_its_type_and_the_debug_switch():
    from gentlerl.apps.errors import one_line

    assert one_line(ValueError("invalid:\n  - a\n  - b")) == "invalid: a; b"
    assert one_line(KeyError("x")) == "KeyError: 'x' (GENTLERL_DEBUG=1 shows the traceback)"


def test_a_ctrl_c_masked_by_a_library_error_still_reads_as_interrupted():
    from gentlerl.apps.errors import interrupted

    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("Converting a tensordict to boolean value is not permitted")  # noqa: B904
    except RuntimeError as err:
        masked = err
    assert interrupted(masked) and not interrupted(RuntimeError("a real bug"))
