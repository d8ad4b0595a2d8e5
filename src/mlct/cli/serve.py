"""`mlct serve`: the JSON API and the web page."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import THREADS_HELP, Commands, thread_count


def run(args: argparse.Namespace) -> int:
    from mlct.generate.load import check_options
    from mlct.serve import run_server

    check_options(args.device, "float32", args.backend)  # before the model loads
    run_server(args.model, host=args.host, port=args.port, device=args.device, token=args.token,
               backend=args.backend, threads=args.threads)
    return 0


def _port(text: str) -> int:
    # Checked here: uvicorn would take 99999 and fail with an OverflowError once the model loaded.
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"a TCP port is 0..65535, got {port}")
    return port


def add_parser(commands: Commands) -> None:
    serve = commands.add_parser("serve", help="the JSON API and the web page (real-time "
                                "generation in the browser)")
    serve.add_argument("--model", type=Path, default=None,
                       help="model directory (default: the bundled model)")
    serve.add_argument("--host", default="127.0.0.1", help="default 127.0.0.1 (this machine)")
    serve.add_argument("--port", type=_port, default=8000, help="default 8000")
    serve.add_argument("--device", default=None, help="cpu or cuda (default: cuda if available)")
    serve.add_argument("--backend", default="auto",
                       help="auto (default: cuda-graphs on a GPU, else onnx when onnxruntime "
                       "is installed), torch, onnx (ONNX Runtime on the CPU), onnx-int8 (its "
                       "denoiser in int8: faster, other motions) or cuda-graphs")
    serve.add_argument("--threads", type=thread_count, default=None, help=THREADS_HELP)
    serve.add_argument("--token", default=None,
                       help="require 'Authorization: Bearer TOKEN' on POST /generate "
                       "(default: $MLCT_TOKEN; the page takes it as #token=TOKEN)")
    serve.set_defaults(func=run)
