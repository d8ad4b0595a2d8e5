"""What the command modules share: the parser class, and the type of what each one adds its
sub-commands to."""

from __future__ import annotations

import argparse


class Parser(argparse.ArgumentParser):
    """argparse that reports usage errors in one line (exit 2), without the usage dump."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"mlct: error: {message}\n")


Commands = argparse._SubParsersAction  # what add_subparsers returns; add_parser adds to it


def thread_count(text: str) -> int:
    """--threads: a whole number of at least 1 (argparse's type: a bad one is a usage error)."""
    try:
        threads = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    if threads < 1:
        raise argparse.ArgumentTypeError(f"at least 1 thread, got {threads}")
    return threads


THREADS_HELP = ("CPU threads for inference (PyTorch's, and ONNX Runtime's per graph; default: "
                "one per core, or $OMP_NUM_THREADS)")
