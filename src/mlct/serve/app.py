"""The HTTP API and the web page of `mlct serve` (FastAPI).

    POST /generate  texts -> motions (JSON) or one motion as a file (npy, bvh, gif, glb, fbx,
                    vrma, npz; `rig` retargets bvh, glb and fbx); each motion's
                    "unknown_parts" (a file's X-Mlct-Unknown-Parts header) lists the parts of
                    its prompt the model does not know, [] when it knows them all
    GET  /health    model, limits, queue and batching figures
    GET  /docs      the OpenAPI page;  GET /  the web page (static/, plotly.js from its wheel)

Every error is JSON {"detail": "one line"}: 400 malformed JSON, 401 no or a wrong token (with
--token), 413 body too large, 415 not JSON, 422 a value out of bounds, 503 queue full. Requests
are checked before they are queued; generation runs on the batcher's one worker thread
(batcher.py).

(No `from __future__ import annotations` here: FastAPI reads the route's body annotation, a class
built per app, at runtime.)
"""

import asyncio
import json
import logging
import secrets
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi_offline import FastAPIOffline
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

from mlct import __version__
from mlct.errors import MlctError, first_line
from mlct.generate.compose.critic import MAX_CANDIDATES
from mlct.generate.output.exports import export_bytes, motion_json
from mlct.generate.files import slug
from mlct.serve.batcher import DEFAULT_LENGTH, Batcher, QueueFull, ServerClosing
from mlct.serve.schemas import Limits, one_line, request_model
from mlct.serve.settings import ServeSettings
from mlct.serve.three_files import three_dir

log = logging.getLogger(__name__)

STATIC = Path(__file__).resolve().parent / "static"
DEFAULT_SECONDS = 5.0
# The page's gallery: captions in the procedural benchmark's style (mlct.data.synth), so the
# bundled model knows them. Warm-up encodes them, so a gallery click skips the text encoder.
EXAMPLES = (  # families the bundled model does best by its read-outs (docs/model_card.md)
    "a person walks forward at a brisk pace.",
    "a man jogs straight ahead.",
    "a person runs straight ahead.",
    "the figure sits down on an invisible chair and stands back up.",
    "a man bows politely.",
    "a person reaches up high and leans to one side.",
    "a person walks backward.",
    "a man walks forward, then bows.",
    "the woman stands quietly.",
)
FASTAPI_BODY_ERROR = "There was an error parsing the body"  # FastAPI's words, e.g. for bad UTF-8
MEDIA_TYPES = {"npy": "application/octet-stream", "bvh": "text/plain; charset=utf-8",
               "gif": "image/gif", "glb": "model/gltf-binary", "vrma": "model/gltf-binary",
               "fbx": "application/octet-stream", "npz": "application/octet-stream"}


def create_app(generator: Any, settings: ServeSettings | None = None) -> FastAPI:
    """The app serving `generator` (a MotionGenerator, or anything with its interface)."""
    settings = settings or ServeSettings()
    fps = float(generator.skeleton.fps)
    limits = Limits(settings.max_text_chars, settings.max_texts,
                    settings.frame_limit(generator.max_frames), settings.max_nfe, fps)
    default_frames = min(limits.max_frames, round(DEFAULT_SECONDS * fps))
    GenerateRequest = request_model(limits)
    batcher = Batcher(generator, settings.max_batch, settings.batch_wait_ms / 1000,
                      settings.queue_depth, default_frames, limits.max_frames)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        batcher.start()
        if settings.warmup:  # loads the text encoder and warms the kernels before any request
            for start in range(0, len(EXAMPLES), settings.max_batch):
                texts = list(EXAMPLES[start:start + settings.max_batch])
                await asyncio.wrap_future(batcher.submit(texts, [default_frames] * len(texts),
                                                         None, [0] * len(texts)))
        yield
        batcher.stop()

    # FastAPIOffline: FastAPI whose /docs (Swagger UI 5) and /redoc pages load their scripts from
    # its own wheel, not from a CDN, so the OpenAPI page works offline.
    app = FastAPIOffline(title="mlct", version=__version__, lifespan=lifespan,
                         description="Real-time text-to-motion (Motion Latent Consistency "
                         "Training). The web page is at /.")
    app.state.batcher = batcher
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes)
    if settings.token is not None:  # added last: it runs first, before the body is read
        app.add_middleware(BearerAuth, token=settings.token)
    _add_error_handlers(app)

    @app.post("/generate", summary="Text to motion",
              responses={200: {"description": "motions as JSON, or one motion as a file"},
                         401: {"description": "the server needs 'Authorization: Bearer "
                               "<token>' (mlct serve --token)"},
                         503: {"description": "the queue is full; retry shortly"}})
    async def generate(body: GenerateRequest) -> Response:  # type: ignore[valid-type]
        received = time.perf_counter()
        texts = body.prompts
        seeds = body.seeds(draw=secrets.randbelow(2**31))
        try:
            # no length asked: the model's default for each text, picked on its thread
            # (batcher.DEFAULT_LENGTH: 5 s, or what the prompt's actions take, as the CLI's)
            frames, control = body.frames(DEFAULT_LENGTH), None
            if body.control is not None:  # one motion, generated alone (generate/control/controlled.py)
                frames, control = _control_of(generator, body, default_frames)
            elif body.lengths is None and body.seconds is None:
                frames = _stated_frames(texts, frames, limits)
            future = batcher.submit(texts, frames, body.nfe, seeds, control, body.candidates)
        except QueueFull as error:
            return _error(503, str(error), {"Retry-After": "1"})
        except MlctError as error:
            return _error(422, str(error))
        try:
            result = await asyncio.wrap_future(future)
        except MlctError as error:
            return _error(422, str(error))
        except ServerClosing as error:
            return _error(503, str(error))
        except Exception as error:  # noqa: BLE001 - the batcher logged it; answer, keep serving
            return _error(500, f"generation failed ({type(error).__name__}); "
                          "the server keeps running")
        nfe = body.nfe if body.nfe is not None else generator.default_nfe
        candidates = (body.candidates if body.candidates is not None
                      else getattr(generator, "candidates", 1))
        timing = {"queue_ms": round(result.queue_s * 1e3, 1),
                  "generate_ms": round(result.generate_s * 1e3, 1),
                  "batch_size": result.batch_size}
        if body.in_place:
            result.motions = [m.in_place() for m in result.motions]
        if body.format == "json":
            # unknown_parts: the prompt's parts the model does not know (generate/
            # compose/unknown_prompts.py), [] when it knows them all
            motions = await run_in_threadpool(
                lambda: [{**motion_json(m), "seed": s, "nfe": nfe, "candidates": candidates,
                          "unknown_parts": list(getattr(m, "unknown_parts", ()))}
                         for m, s in zip(result.motions, seeds)])
            timing["server_ms"] = round((time.perf_counter() - received) * 1e3, 1)
            return JSONResponse({"motions": motions, "timing": timing})
        data = await run_in_threadpool(export_bytes, result.motions[0], f".{body.format}",
                                       False, body.rig)
        timing["server_ms"] = round((time.perf_counter() - received) * 1e3, 1)
        rig = f"_{body.rig}" if body.rig else ""
        name = f"{slug(texts[0])}_seed{seeds[0]}{rig}.{body.format}"
        return Response(data, media_type=MEDIA_TYPES[body.format], headers={
            "Content-Disposition": f'attachment; filename="{name}"',
            "X-Mlct-Seed": str(seeds[0]), "X-Mlct-Nfe": str(nfe),
            "X-Mlct-Candidates": str(candidates),
            # a JSON list, ASCII-escaped as a header must be
            "X-Mlct-Unknown-Parts": json.dumps(list(getattr(result.motions[0], "unknown_parts",
                                                            ()))),
            "Server-Timing": ", ".join(f"{k[:-3]};dur={v}" for k, v in timing.items()
                                       if k.endswith("_ms"))})

    @app.get("/health", summary="Model, limits, queue and batching figures")
    async def health() -> dict[str, Any]:
        return {"status": "ok", "version": __version__, "model": _model_info(generator),
                "limits": {"max_text_chars": limits.max_text_chars,
                           "max_texts": limits.max_texts, "max_frames": limits.max_frames,
                           "max_seconds": limits.max_seconds, "max_nfe": limits.max_nfe,
                           "max_body_bytes": settings.max_body_bytes,
                           "queue_depth": settings.queue_depth,
                           "default_frames": default_frames,
                           "default_length": "default_frames, or longer where the prompt's "
                                             "actions take longer (as mlct generate)"},
                "queue": batcher.stats()}

    @app.get("/examples", summary="Example prompts (the page's gallery)")
    async def examples() -> dict[str, list[str]]:
        return {"examples": list(EXAMPLES)}

    @app.get("/", include_in_schema=False)
    async def page() -> FileResponse:
        return FileResponse(STATIC / "index.html")

    @app.get("/vendor/plotly.min.js", include_in_schema=False)
    async def plotly_js() -> FileResponse:
        # plotly.js as the plotly wheel ships it: nothing third-party is copied into mlct.
        path = resources.files("plotly") / "package_data" / "plotly.min.js"
        return FileResponse(str(path), media_type="text/javascript",
                            headers={"Cache-Control": "public, max-age=86400"})

    _mount_three(app)  # before /static: the first mount that matches serves
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    return app


def _mount_three(app: FastAPI) -> None:
    """three.js at /static/three/ from the pinned npm package (serve/three_files.py); without
    it the page keeps its skeleton view and says why the humanoid is missing."""
    try:
        folder = three_dir(fetch=False)  # run_server fetched it, when it could
    except (MlctError, OSError) as error:
        log.warning("the web page's 3D humanoid is off: three.js unavailable (%s)",
                    first_line(error))
        return
    app.mount("/static/three", StaticFiles(directory=folder), name="three")


def _model_info(generator: Any) -> dict[str, Any]:
    meta = generator.meta
    return {"sampler": meta.get("sampler"), "skeleton": generator.skeleton.name,
            "fps": float(generator.skeleton.fps), "max_frames": generator.max_frames,
            "default_nfe": generator.default_nfe, "text_encoder": meta.get("text_encoder"),
            "step": meta.get("step"), "backend": getattr(generator, "backend", "torch"),
            # best of N by the model's critic: its default N (1 without a critic) and the most
            "candidates": getattr(generator, "candidates", 1),
            "max_candidates": MAX_CANDIDATES if getattr(generator, "critic", None) else 1}


def _bearer_matches(header: str | None, token: str) -> bool:
    """A constant-time comparison of an Authorization header with the expected bearer token."""
    scheme, _, given = (header or "").partition(" ")
    return scheme.lower() == "bearer" and secrets.compare_digest(given.strip().encode(),
                                                                 token.encode())


def _control_of(generator: Any, body: Any, default_frames: int) -> tuple[list[int], Any]:
    """The frames and the Control of a request's "control" field (the length an edit implies
    when none was asked); MlctError (422) for a control that does not fit."""
    from mlct.generate.control.schema import control_from_dict

    frames = body.frames(default_frames)[0]
    control = control_from_dict(body.control, generator.skeleton, "control", frames)
    if body.lengths is None and body.seconds is None and control.natural_length() is not None:
        frames = control.natural_length()
    return [frames], control.check(frames, generator.skeleton)


def _error(status: int, detail: str, headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status, headers=headers)


def _stated_frames(texts: list[str], frames: list[int | None], limits: Limits
                   ) -> list[int | None]:
    """The default length, except where a prompt says how long ("... for 8 seconds"), as the
    CLI and the Python API read it (compose.lengths.stated_lengths); MlctError (422) past the limit."""
    from mlct.generate.compose.lengths import stated_lengths

    _, stated = stated_lengths(texts)
    out = []
    for text, default, seconds in zip(texts, frames, stated):
        if seconds is None:
            out.append(default)
            continue
        wanted = round(seconds * limits.fps)
        if not 1 <= wanted <= limits.max_frames:
            raise MlctError(f"{text!r} says {seconds:g} s; this server makes motions of at most "
                            f"{limits.max_seconds:.1f} s (give 'seconds')")
        out.append(wanted)
    return out


def _add_error_handlers(app: FastAPI) -> None:
    """Every error as {"detail": "one line"}, with the status that names its kind."""

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Any, error: RequestValidationError) -> JSONResponse:
        errors = list(error.errors())
        first = errors[0] if errors else {}
        if first.get("type") == "json_invalid":
            where = first.get("loc", ("body", 0))[-1]
            reason = (first.get("ctx") or {}).get("error", "")
            return _error(400, f"malformed JSON at character {where}: {reason}".rstrip(": "))
        if first.get("type") == "model_attributes_type" and isinstance(first.get("input"), bytes):
            return _error(415, "send the body as JSON with Content-Type: application/json")
        return _error(422, one_line(errors))

    @app.exception_handler(HTTPException)
    async def http_error(request: Any, error: HTTPException) -> JSONResponse:
        detail = str(error.detail)
        if error.status_code == 400 and detail == FASTAPI_BODY_ERROR:  # a body json.loads
            detail = "the request body cannot be read as JSON (not UTF-8 text?)"  # can't decode
        return _error(error.status_code, detail, getattr(error, "headers", None))

    @app.exception_handler(MlctError)
    async def user_error(request: Any, error: MlctError) -> JSONResponse:
        return _error(422, str(error))

    @app.exception_handler(Exception)
    async def server_error(request: Any, error: Exception) -> JSONResponse:
        log.exception("unhandled error")
        return _error(500, f"internal error ({type(error).__name__}); the server keeps running")


Scope = dict[str, Any]
Receive = Callable[[], Awaitable[dict[str, Any]]]
Send = Callable[[dict[str, Any]], Awaitable[None]]


class BodyLimit:
    """413 for a body over max_bytes: by its Content-Length before reading, else while reading.

    (Starlette's own limit answers in plain text; every error here is JSON.)"""

    def __init__(self, app: Callable[..., Awaitable[None]], max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        too_large = f"the request body exceeds {self.max_bytes} bytes"
        declared = dict(scope.get("headers", ())).get(b"content-length")
        if declared is not None and (not declared.isdigit() or int(declared) > self.max_bytes):
            await _send_json(send, 413, {"detail": too_large})
            return
        seen = 0

        async def limited() -> dict[str, Any]:
            nonlocal seen
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.max_bytes:  # a chunked body, announced by no Content-Length
                raise HTTPException(413, too_large)  # the app's handler answers it
            return message

        await self.app(scope, limited, send)


class BearerAuth:
    """401 for POST /generate without the server's bearer token (mlct serve --token), before
    its body is read: a client without the token learns nothing of how a request is checked
    (a 422 naming a limit, a 413) and makes the server parse nothing."""

    def __init__(self, app: Callable[..., Awaitable[None]], token: str) -> None:
        self.app = app
        self.token = token

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["path"] == "/generate" and scope["method"] == "POST":
            header = dict(scope.get("headers", ())).get(b"authorization")
            given = header.decode("latin-1") if header is not None else None
            if not _bearer_matches(given, self.token):
                await _send_json(send, 401, {"detail": UNAUTHORIZED},
                                 [(b"www-authenticate", b"Bearer")])
                return
        await self.app(scope, receive, send)


UNAUTHORIZED = ("this server needs 'Authorization: Bearer <token>' (mlct serve --token); the web "
                "page takes it as #token=... in its URL")


async def _send_json(send: Send, status: int, content: dict[str, Any],
                     headers: list[tuple[bytes, bytes]] | None = None) -> None:
    body = json.dumps(content).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()), *(headers or [])]})
    await send({"type": "http.response.body", "body": body})
