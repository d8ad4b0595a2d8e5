"""CUDA graphs: a function of fixed-shape tensors captured once, then replayed as one launch.

Why: at batch 1 the GPU does a few microseconds of arithmetic per kernel and the host spends
~10 us launching each of the sampler's hundreds of kernels (docs/performance.md). A
captured graph replays them all with one call. The cost: inputs and outputs live in fixed
buffers (copied in, read out before the next replay), the shapes are fixed per graph (one graph
per shape key, kept least-recently-used), and the function may not read the device while it is
captured (`capturing()` lets input checks step aside; the caller checks on the host).

`GraphCache(fn)(key, *tensors, read=copy_out)` runs fn(key, *tensors) and returns
copy_out(its outputs): on a CUDA device through a graph captured for (key, the tensors' shapes
and dtypes); on any other device directly, so the same code path runs (and is tested) on the
CPU. Filling the inputs, replaying and `read` happen under one lock, so threads may share it.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Callable, Hashable

import torch
from torch import Tensor

Outputs = Any  # a tensor or a tuple of tensors


def capturing() -> bool:
    """True while a CUDA graph is being captured on the current stream: reading a tensor's
    value on the host (int(x), x.tolist()) would fail, so checks that do it step aside."""
    return torch.cuda.is_available() and torch.cuda.is_current_stream_capturing()


@dataclass
class _Graph:
    graph: Any  # torch.cuda.CUDAGraph
    inputs: tuple[Tensor, ...]
    outputs: Outputs


class GraphCache:
    """fn(key, *tensors) replayed from CUDA graphs, one per (key, shapes, dtypes).

    The outputs are the graph's own buffers, overwritten by the next call: `read` copies what
    the caller needs out of them (without it the caller must not share the cache between
    threads). max_graphs bounds the memory the graphs hold (each keeps its activations' pool)."""

    def __init__(self, fn: Callable[..., Outputs], max_graphs: int = 16,
                 warmup: int = 2) -> None:
        self.fn = fn
        self.max_graphs = max_graphs
        self.warmup = warmup
        self._graphs: OrderedDict[Hashable, _Graph] = OrderedDict()
        self._lock = threading.Lock()
        self.captures = 0  # how many graphs were captured (a test reads it)

    def __call__(self, key: Hashable, *tensors: Tensor,
                 read: Callable[[Outputs], Any] = lambda outputs: outputs) -> Any:
        if not tensors or tensors[0].device.type != "cuda":
            return read(self.fn(key, *tensors))
        full_key = (key, *((tuple(t.shape), t.dtype) for t in tensors))
        with self._lock:
            entry = self._graphs.get(full_key)
            if entry is None:
                entry = self._capture(key, tensors)
                self._graphs[full_key] = entry
                while len(self._graphs) > self.max_graphs:
                    self._graphs.popitem(last=False)  # the least recently used
            self._graphs.move_to_end(full_key)
            for static, value in zip(entry.inputs, tensors):
                static.copy_(value, non_blocking=True)
            entry.graph.replay()
            return read(entry.outputs)

    def _capture(self, key: Hashable, tensors: tuple[Tensor, ...]) -> _Graph:
        inputs = tuple(t.clone() for t in tensors)
        # Warm-up on a side stream, as torch.cuda.graphs advises: lazy initialisations (cuBLAS
        # handles and workspaces, autotuning) must happen before the capture, not in it.
        side = torch.cuda.Stream(device=inputs[0].device)
        side.wait_stream(torch.cuda.current_stream(inputs[0].device))
        with torch.cuda.stream(side):
            for _ in range(self.warmup):
                self.fn(key, *inputs)
        torch.cuda.current_stream(inputs[0].device).wait_stream(side)
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            outputs = self.fn(key, *inputs)
        self.captures += 1
        return _Graph(graph, inputs, outputs)

    def clear(self) -> None:
        self._graphs.clear()
