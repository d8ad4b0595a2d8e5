"""The one-line error helper that every 'cannot read X (reason)' message quotes through."""

from __future__ import annotations

from mlct.errors import first_line


def test_first_line_of_a_message_and_of_an_empty_one() -> None:
    assert first_line(ValueError("bad header\nTraceback details")) == "bad header"
    assert first_line(OSError("\n  disk full  \n")) == "disk full"
    assert first_line(KeyError()) == "KeyError"  # str() is empty: the type names it
    assert first_line(RuntimeError(""), empty="") == ""
