"""Dynamic batching: concurrent requests share one model call, on one worker thread.

Requests wait in a bounded queue (full: `QueueFull`, the server's 503). The worker takes the
oldest request, waits up to `wait_s` for more (everything that queued while the model was busy
joins at once), splits what it took by NFE (a batch samples with one step count) and runs each
group as one `generate` call. Each text carries its own seed, so a motion does not depend on
what it was batched with. Torch is only ever called from the worker thread.
"""

from __future__ import annotations

import concurrent.futures
import logging
import queue
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from mlct.errors import MlctError

log = logging.getLogger(__name__)
# A length the model picks on its thread: its default for the text (5 s, or what the prompt's
# actions take: MotionGenerator.default_seconds), within the server's limit.
DEFAULT_LENGTH = -1


class Generator(Protocol):
    """What the batcher needs of a MotionGenerator (tests pass a fake); `control` is passed only
    for a request that has one."""

    def generate(self, texts: Sequence[str], lengths: Any = None, *,
                 nfe: int | None = None, seed: Sequence[int] | None = None,
                 control: Any = None, candidates: int | None = None) -> list[Any]: ...


class QueueFull(Exception):
    """The queue holds `depth` requests already: the client should retry later."""


class ServerClosing(Exception):
    """The server stopped before this request ran."""


@dataclass
class Result:
    """One request's motions and how it was served."""

    motions: list[Any]
    batch_size: int  # texts in the model call that made these motions
    queue_s: float  # submitted -> its batch started
    generate_s: float  # the model call


@dataclass
class _Job:
    texts: list[str]
    lengths: list[int]
    nfe: int | None
    seeds: list[int]
    future: concurrent.futures.Future = field(default_factory=concurrent.futures.Future)
    submitted: float = field(default_factory=time.perf_counter)
    control: Any = None  # a generate.control.Control: one text, run alone (never merged)
    candidates: int | None = None  # best-of-N; None: the model's default


_STOP = object()
# How long after requests last overlapped (a batch of several, or more waiting) the model's
# threads keep from spinning (the onnx backend's `spinning`). The load meter behind its default
# counts other processes only, and a server's own threads (HTTP, the responses' export) work
# beside the model while requests overlap: 4 concurrent clients on 2 cores got 48-52 motions/s
# with the threads spinning and 55-57 without, while one client's round trip took 20 ms
# spinning against 25 (bench/serve_latency.py; docs/performance.md).
OVERLAP_WINDOW_S = 1.0


class Batcher:
    """A worker thread that batches `generate` calls from many requests."""

    def __init__(self, generator: Generator, max_batch: int = 32, wait_s: float = 0.002,
                 queue_depth: int = 64, default_frames: int = 100,
                 max_frames: int | None = None) -> None:
        self.generator = generator
        # DEFAULT_LENGTH: the generator's default_seconds (a fake without one: default_frames),
        # at most max_frames (the server's limit)
        self.default_frames = default_frames
        self.max_frames = max_frames
        self.max_batch = max_batch
        self.wait_s = wait_s
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_depth)
        self._carry: Any = None  # a request taken that did not fit in the last batch
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._sizes: Counter[int] = Counter()  # batch size -> model calls of that size
        self._requests = 0
        self._overlapped = -float("inf")  # perf_counter() when requests last overlapped

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="mlct-batcher", daemon=True)
            self._thread.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Fail what is still queued, let the running batch finish, end the thread."""
        while True:
            try:
                job = self._queue.get_nowait()
            except queue.Empty:
                break
            if isinstance(job, _Job):
                job.future.set_exception(ServerClosing("the server is shutting down"))
        if self._thread is not None:
            self._queue.put(_STOP)
            self._thread.join(timeout)
            self._thread = None

    def submit(self, texts: list[str], lengths: list[int], nfe: int | None,
               seeds: list[int], control: Any = None, candidates: int | None = None
               ) -> concurrent.futures.Future:
        """Queue a request; its future gets a Result. QueueFull when the queue is full.
        control: a Control for one text; such a request is generated alone, on this worker
        thread like every other (the model is never called from two threads)."""
        if len(texts) > self.max_batch:
            raise MlctError(f"{len(texts)} texts exceed the batch limit of {self.max_batch}")
        job = _Job(list(texts), list(lengths), nfe, list(seeds), control=control,
                   candidates=candidates)
        try:
            self._queue.put_nowait(job)
        except queue.Full:
            raise QueueFull(f"the server is busy ({self._queue.maxsize} requests waiting); "
                            "retry shortly") from None
        return job.future

    def stats(self) -> dict[str, Any]:
        """Queue depth now; model calls by batch size so far (dynamic batching at work)."""
        with self._lock:
            sizes = dict(sorted(self._sizes.items()))
            requests = self._requests
        return {"queued": self._queue.qsize(), "capacity": self._queue.maxsize,
                "requests": requests, "batches": sum(sizes.values()),
                "largest_batch": max(sizes, default=0),
                "batch_sizes": {str(k): v for k, v in sizes.items()}}

    # --- the worker thread -------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            jobs = self._next_batch()
            if jobs is None:
                return
            by_call: dict[tuple[int | None, int | None], list[_Job]] = {}
            for job in jobs:  # one model call per step count and candidate count
                by_call.setdefault((job.nfe, job.candidates), []).append(job)
            for group in by_call.values():
                self._run(group)

    def _next_batch(self) -> list[_Job] | None:
        """The oldest request and those that arrive within wait_s, up to max_batch texts."""
        first = self._carry if self._carry is not None else self._queue.get()
        self._carry = None
        if first is _STOP:
            return None
        jobs, items = [first], len(first.texts)
        if first.control is not None:
            return jobs
        deadline = time.perf_counter() + self.wait_s
        while items < self.max_batch:
            left = deadline - time.perf_counter()
            try:
                job = self._queue.get(timeout=left) if left > 0 else self._queue.get_nowait()
            except queue.Empty:
                break
            if job is _STOP or job.control is not None or items + len(job.texts) > self.max_batch:
                self._carry = job
                break
            jobs.append(job)
            items += len(job.texts)
        return jobs

    def _run(self, jobs: list[_Job]) -> None:
        """One model call for jobs of one NFE; if it fails on input, each job alone."""
        live = [job for job in jobs if job.future.set_running_or_notify_cancel()]
        if not live:
            return
        texts = [text for job in live for text in job.texts]
        started = time.perf_counter()
        self._spin_unless_overlapping(len(live) > 1 or not self._queue.empty(), started)
        try:
            if live[0].control is not None:  # alone in its batch (_next_batch)
                motions = self.generator.generate(texts, lengths=live[0].lengths[0],
                                                  nfe=live[0].nfe, seed=live[0].seeds,
                                                  control=live[0].control)
            else:
                extra = ({"candidates": live[0].candidates}
                         if live[0].candidates is not None else {})
                lengths = [n for job in live for n in job.lengths]
                if None in lengths:  # seconds "auto": from the text, on the model's thread
                    lengths = _auto_lengths(self.generator, texts, lengths)
                if DEFAULT_LENGTH in lengths:  # no length asked: the model's default
                    lengths = self._default_lengths(texts, lengths)
                motions = self.generator.generate(
                    texts, lengths=lengths, nfe=live[0].nfe,
                    seed=[s for job in live for s in job.seeds], **extra)
        except MlctError as error:
            if len(live) == 1:
                live[0].future.set_exception(error)
                return
            for job in live:  # one bad request must not fail the others
                retry = _Job(job.texts, job.lengths, job.nfe, job.seeds, submitted=job.submitted,
                             control=job.control, candidates=job.candidates)
                self._run([retry])
                _forward(retry.future, job.future)
            return
        except Exception as error:
            log.exception("generation failed for %d texts", len(texts))
            for job in live:
                job.future.set_exception(error)
            return
        elapsed = time.perf_counter() - started
        with self._lock:
            self._sizes[len(texts)] += 1
            self._requests += len(live)
        start = 0
        for job in live:
            job.future.set_result(Result(motions[start:start + len(job.texts)], len(texts),
                                         started - job.submitted, elapsed))
            start += len(job.texts)


    def _spin_unless_overlapping(self, overlapping: bool, now: float) -> None:
        """The `spinning` of the generator's networks (where they have one, the onnx
        backend's): False within OVERLAP_WINDOW_S of requests overlapping, else None (the
        machine's load decides)."""
        if overlapping:
            self._overlapped = now
        networks = getattr(self.generator, "networks", self.generator)
        if hasattr(networks, "spinning"):
            networks.spinning = False if now - self._overlapped < OVERLAP_WINDOW_S else None

    def _default_lengths(self, texts: list[str], lengths: list[int]) -> list[int]:
        """Each DEFAULT_LENGTH replaced by the model's default for its text, as the CLI's."""
        need = [i for i, n in enumerate(lengths) if n == DEFAULT_LENGTH]
        pick = getattr(self.generator, "default_seconds", None)
        frames = ([self.generator.frames_for(s) for s in pick([texts[i] for i in need])]
                  if pick is not None else [self.default_frames] * len(need))
        out = list(lengths)
        for i, n in zip(need, frames):
            out[i] = n if self.max_frames is None else min(n, self.max_frames)
        return out


def _auto_lengths(generator: Any, texts: list[str], lengths: list[int | None]) -> list[int]:
    """The lengths with each None (seconds "auto") taken from its text by the model's
    duration model (MotionGenerator.auto_seconds); MlctError when it has none."""
    need = [i for i, n in enumerate(lengths) if n is None]
    seconds = generator.auto_seconds([texts[i] for i in need])
    out = list(lengths)
    for i, s in zip(need, seconds):
        out[i] = generator.frames_for(s)
    return out  # type: ignore[return-value]


def _forward(source: concurrent.futures.Future, target: concurrent.futures.Future) -> None:
    """Copy a finished future's outcome onto another (already running) future."""
    error = source.exception()
    if error is not None:
        target.set_exception(error)
    else:
        target.set_result(source.result())
