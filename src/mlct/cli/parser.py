"""What the command modules share: the parser class, and the type of what each one adds its
sub-commands to."""

from __future__ import annotations

import argparse


class Parser(argparse.ArgumentParser):
    """argparse that reports usage errors in one line (exit 2), without the usage dump."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"mlct: error: {message}\n")


Commands = argparse._SubParsersAction  # what add_subparsers returns; add_parser adds to it
