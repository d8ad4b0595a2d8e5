"""The `mlct` command: parse, call the library, print. No logic lives here.

Each command group is a module that holds its sub-parsers beside their handlers (data.py:
`mlct data ...`; train.py: `mlct train ...`; ...), each with `add_parser(commands)`; this file
puts them together and turns the errors a user can cause into one line and an exit code. A
handler imports what it runs when it runs, so that `mlct --help` stays fast.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from typing import Iterator

from mlct.cli import (convert, data, demo, export, export_web, generate, render, retarget, serve,
                      train)
from mlct.cli import eval as evaluate  # (not the builtin)
from mlct.cli.parser import Parser
from mlct.errors import MlctError, MlctWarning

# The extra that brings each library a light install (`pip install mlct`) leaves out: a command
# that reaches one says so in one line (exit 2) instead of a traceback.
EXTRA_OF = {"torch": "train", "transformers": "train", "sentence_transformers": "train",
            "tensorboard": "train", "onnx_ir": "train", "bvhio": "train", "fastapi": "serve",
            "fastapi_offline": "serve", "uvicorn": "serve", "plotly": "serve",
            "pygltflib": "export"}

# The one-off commands' numpy work is on small arrays, where OpenBLAS's worker threads (one per
# core, started when numpy loads) buy nothing and spin for ~0.1 s each beside ONNX Runtime's:
# on one thread `mlct generate` starts ~0.07 s sooner on 2 cores (docs/performance.md, "Cold
# start"). An $OPENBLAS_NUM_THREADS of the user's own stays.
ONE_BLAS_THREAD = ("generate", "render", "retarget")

# in the order `mlct --help` lists their commands
COMMANDS = (data, demo, train, evaluate, export, export_web, convert, serve, generate, render,
            retarget)


def _version() -> str:
    from mlct import __version__

    return f"mlct {__version__}"


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="mlct", description="Real-time text-to-motion generation (MLCT).")
    parser.add_argument("--version", action="version", version=_version())
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMANDS:
        module.add_parser(commands)
    return parser


@contextlib.contextmanager
def _notes_on_one_line() -> Iterator[None]:
    """mlct's notices (MlctWarning) as "mlct: note: ..." lines on stderr, each time, other
    warnings as Python shows them."""
    show = warnings.showwarning

    def one_line(message, category, filename, lineno, file=None, line=None):  # type: ignore
        if issubclass(category, MlctWarning):
            print(f"mlct: note: {message}", file=sys.stderr, flush=True)
        else:
            show(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("always", MlctWarning)
        warnings.showwarning = one_line
        yield


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    # key=value overrides may come anywhere after `mlct train STAGE` (argparse would only take
    # them right after the stage); anything else left over is an error, as parse_args makes it.
    overrides = [item for item in extra if "=" in item and not item.startswith("-")]
    unknown = [item for item in extra if item not in overrides]
    if overrides and not hasattr(args, "overrides"):  # only `mlct train ae|cm|diffusion`
        unknown = extra
    if unknown:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if overrides:
        args.overrides = list(args.overrides) + overrides
    args.argv = list(sys.argv[1:] if argv is None else argv)  # reports record the command
    if args.command in ONE_BLAS_THREAD and "numpy" not in sys.modules:  # (read at its import)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    try:
        with _notes_on_one_line():
            return args.func(args)
    except MlctError as error:
        print(f"mlct: error: {error}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as error:
        library = (error.name or "").split(".")[0]
        if library not in EXTRA_OF:
            raise
        print(f"mlct: error: mlct {args.command} needs {library}, which this install lacks: "
              f"pip install 'mlct[{EXTRA_OF[library]}]'", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # `mlct ... | head`: the reader left; that is not an error. Point stdout at devnull so
        # that the interpreter's final flush does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as error:
        # A file the user named cannot be read or written: say which, in one line.
        where = f": {error.filename}" if error.filename else ""
        print(f"mlct: error: {error.strerror or error}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mlct: interrupted", file=sys.stderr)
        return 130
