"""The conv decoder's two halves (body and arm pair) run at once, one core each.

At batch 1 the decoder's convolutions over 200 frames and 96-128 channels split badly across
threads inside one operator: ONNX Runtime on two threads decoded the bundled model's 196 frames
in 1.55 ms against 1.80 on one, and its parallel executor, which could run the two independent
halves side by side, took 1.90 ms. The halves are independent until their columns are put back in
feature order, so here each runs in a session of its own on one thread, the lighter one in a
worker thread while the caller's thread runs the heavier (ONNX Runtime releases the GIL while it
runs): 1.14 ms (docs/performance.md).

The three graphs are cut out of decoder.onnx itself (onnx.utils.Extractor), at the outputs of
each half's last convolution: the body's half, the arm pair's half, and the join (the columns
in feature order, the frames past each length set to 0). So the arithmetic is the decoder's own,
operator for operator (tests/test_onnx.py, the arm-pair model).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np

from mlct.generate.backends.onnx.bundle import DECODER_IO
from mlct.generate.backends.onnx.sampler import fixed_batch
from mlct.onnx_io import session_from_bytes

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

# the stacks' module names, as the exporter writes them into the node names
BODY, ARMS = "/decoder/", "/arm_decoder/"


def half_outputs(graph: Any) -> tuple[str, str] | None:
    """The outputs of the body's and the arm pair's last convolutions in a decoder graph (an
    onnx.ModelProto), or None when it has no arm pair."""
    last: dict[str, str] = {}
    for node in graph.graph.node:
        if node.op_type == "Conv":
            for part in (BODY, ARMS):
                if node.name.startswith(part):
                    last[part] = node.output[0]
    if set(last) != {BODY, ARMS}:
        return None
    return last[BODY], last[ARMS]


class DecoderHalves:
    """A decoder graph (onnx.ModelProto) as three batch-1 sessions, its halves run side by side
    (above), cut at `outputs` (half_outputs); call it with (latent (1, n, d), valid (1, T)
    bool) for the normalized features (1, T, D), or, given the features' `mean` and `std`
    (D,), the features in real units: the join graph undoes the normalization, one pass less
    over the frames in numpy."""

    def __init__(self, graph: Any, outputs: tuple[str, str], mean: np.ndarray | None = None,
                 std: np.ndarray | None = None) -> None:
        from onnx.shape_inference import infer_shapes
        from onnx.utils import Extractor

        (latent, valid), (features,) = DECODER_IO
        extractor = Extractor(infer_shapes(graph))  # it cuts at values whose types it knows
        body, arms = outputs
        self.names = (body, arms)
        cut = {"body": extractor.extract_model([latent, valid], [body]),
               "arms": extractor.extract_model([latent, valid], [arms]),
               "join": extractor.extract_model([body, arms, valid], [features])}
        if mean is not None and std is not None:
            _denormalize(cut["join"], features, mean, std)
        self.sessions = {name: session_from_bytes(fixed_batch(model.SerializeToString(), 1), 1)
                         for name, model in cut.items()}
        # the heavier half (more weights) on the caller's thread, the other handed over: the
        # worker's wake-up then delays the half that finishes first (version 7: its 128-channel
        # arm half 1.06 ms, the 96-channel body 0.76; the halves 1.26 -> 1.18 ms)
        self.handed_over = min(("body", "arms"), key=lambda name: _weight_bytes(cut[name]))
        self.kept = "arms" if self.handed_over == "body" else "body"
        self.inputs = {name: [i.name for i in s.get_inputs()]
                       for name, s in self.sessions.items()}
        self._worker: ThreadPoolExecutor | None = None
        self._pid = 0  # the process the worker thread belongs to

    @classmethod
    def of(cls, decoder: str | os.PathLike, mean: np.ndarray | None = None,
           std: np.ndarray | None = None) -> DecoderHalves | None:
        """The halves of the decoder graph at `decoder` (mean, std: as the constructor's), or
        None: no arm pair, or no onnx package to cut the graph with."""
        try:
            import onnx
        except ImportError:
            return None
        graph = onnx.load(str(decoder))
        outputs = half_outputs(graph)
        if outputs is None:
            return None
        try:
            return cls(graph, outputs, mean, std)
        except ValueError:  # a graph the cut does not fit (Extractor): the whole decoder runs
            return None

    def _run(self, name: str, feeds: dict[str, np.ndarray]) -> np.ndarray:
        session = self.sessions[name]
        (out,) = session.run(None, {k: feeds[k] for k in self.inputs[name]})
        return out

    def _pool(self) -> ThreadPoolExecutor:
        """The worker thread, made anew in a forked child (a fork copies the pool, not its
        thread: work handed to the copy would never run). (concurrent.futures is imported
        here: ~5 ms of every cold start that never decodes by halves.)"""
        if self._worker is None or self._pid != os.getpid():
            from concurrent.futures import ThreadPoolExecutor

            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mlct-decoder")
            self._pid = os.getpid()
        return self._worker

    def __call__(self, latent: np.ndarray, valid: np.ndarray, side_by_side: bool = True
                 ) -> np.ndarray:
        """side_by_side False: both halves on the caller's thread, one after the other (the
        same sessions, so the same numbers), for a machine whose other cores are busy: there
        the handed-over half waits for a core (OnnxNetworks._decoded)."""
        (latent_name, valid_name), _ = DECODER_IO
        feeds = {latent_name: latent, valid_name: valid}
        if side_by_side:
            other = self._pool().submit(self._run, self.handed_over, feeds)
            out = {self.kept: self._run(self.kept, feeds), self.handed_over: other.result()}
        else:
            out = {name: self._run(name, feeds) for name in (self.kept, self.handed_over)}
        body_name, arms_name = self.names
        return self._run("join", {body_name: out["body"], arms_name: out["arms"],
                                  valid_name: valid})


def _denormalize(join: Any, features: str, mean: np.ndarray, std: np.ndarray) -> None:
    """Make the join graph's output `features` * std + mean, in place."""
    from onnx import helper, numpy_helper

    for node in join.graph.node:
        node.output[:] = [name if name != features else "normalized" for name in node.output]
    join.graph.initializer.extend([
        numpy_helper.from_array(np.asarray(std, np.float32), "feature_std"),
        numpy_helper.from_array(np.asarray(mean, np.float32), "feature_mean")])
    join.graph.node.extend([
        helper.make_node("Mul", ["normalized", "feature_std"], ["scaled"]),
        helper.make_node("Add", ["scaled", "feature_mean"], [features])])


def _weight_bytes(model: Any) -> int:
    """Bytes of model's initializers: how much work a half of the decoder does, near enough."""
    return sum(len(tensor.raw_data) or 4 * len(tensor.float_data)
               for tensor in model.graph.initializer)
