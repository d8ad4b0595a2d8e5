"""`mlct serve`: a JSON API and a web page over one loaded model, with dynamic batching."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from mlct.serve.settings import ServeSettings

if TYPE_CHECKING:
    from fastapi import FastAPI

__all__ = ["ServeSettings", "create_app", "run_server", "serve_in_thread"]


def create_app(generator: Any, settings: ServeSettings | None = None) -> FastAPI:
    """The FastAPI app over a loaded generator (see mlct.serve.app)."""
    from mlct.serve.app import create_app as _create_app  # lazy: fastapi loads on use

    return _create_app(generator, settings)


def is_loopback(host: str) -> bool:
    """True for addresses only this machine can reach (127.0.0.0/8, ::1, localhost)."""
    import ipaddress

    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False  # a hostname: it may resolve to an outside address


def run_server(model: Any = None, host: str = "127.0.0.1", port: int = 8000,
               device: Any = None, settings: ServeSettings | None = None,
               token: str | None = None, backend: str = "auto",
               threads: int | None = None) -> None:
    """Load the model (None: the bundled one) and serve it until interrupted. token (or the
    MLCT_TOKEN environment variable): POST /generate needs it as a bearer token. backend: the
    inference backend (mlct.load's); the torch one takes a GPU when there is one. threads:
    mlct.load's (the CPU threads inference uses)."""
    import dataclasses
    import os

    import uvicorn

    import mlct
    from mlct.devices import resolve_device

    token = token or os.environ.get("MLCT_TOKEN") or None
    settings = dataclasses.replace(settings or ServeSettings(), token=token)
    if not is_loopback(host) and token is None:
        print(f"mlct serve: warning: listening on {host}: any machine that can reach this one "
              f"may use the API; bind 127.0.0.1 unless you mean it, or require a token "
              f"(--token or MLCT_TOKEN)", file=sys.stderr)
    # a GPU when there is one; the onnx backends run on the CPU
    if device is None and not backend.startswith("onnx"):
        device = resolve_device(None)
    generator = mlct.load(model, device=device, backend=backend, threads=threads)
    _fetch_three()
    uvicorn.run(create_app(generator, settings), host=host, port=port, log_level="info")


def _fetch_three() -> None:
    """three.js for the page's humanoid, fetched once from the npm registry into the cache
    (serve/three_files.py); a server without it keeps the skeleton view."""
    from mlct.errors import MlctError, first_line
    from mlct.serve.three_files import three_dir

    try:
        three_dir()
    except (MlctError, OSError) as error:
        print(f"mlct serve: warning: the page's 3D humanoid is off: {first_line(error)}",
              file=sys.stderr)


@contextlib.contextmanager
def serve_in_thread(app: FastAPI, host: str = "127.0.0.1", port: int = 0,
                    timeout: float = 120.0) -> Iterator[str]:
    """Run app under uvicorn on a background thread (port 0: a free one); yields its URL.

    For tests and benchmarks that need a real socket (a browser, concurrent clients)."""
    import uvicorn

    server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, name="mlct-uvicorn", daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout  # startup includes the model's warm-up
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            server.should_exit = True
            raise RuntimeError(f"the server did not start on {host}:{port}")
        time.sleep(0.02)
    bound = server.servers[0].sockets[0].getsockname()[1]
    try:
        yield f"http://{host}:{bound}"
    finally:
        server.should_exit = True
        thread.join(timeout)
