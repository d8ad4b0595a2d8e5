"""The bundled MiniLM as an ONNX graph: written from minilm.py's network, run by ONNX Runtime.

Only the network (BERT, mean pooling, normalisation: minilm.SentenceNetwork) is the graph; the
tokenizer stays the `tokenizers` library and the batching, padding, token slots and side
contrast are minilm.py's, here in numpy, so the embeddings are the torch encoder's up to float
rounding (tested) and running the graph imports no torch (writing it does).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mlct.errors import MlctError
from mlct.onnx_io import default_threads, export_graph, session, spin_now
from mlct.text.base import TextEncoder
from mlct.text.minilm_files import (MINILM_SPECS, bundled_minilm_path, load_tokenizer,
                                    token_slots_of)
from mlct.text.sides import MIRROR_VERSION, SIDES_SUFFIX, contrast_sides, mirror_sides

if TYPE_CHECKING:
    from torch import Tensor

ONNX_SPECS = MINILM_SPECS  # the text encoders that have an ONNX graph
INPUTS = ("ids", "mask")  # (B, L) int64 each: token ids, 1 for a real token and 0 for padding
OUTPUTS = ("embedding", "states")  # (B, D) unit vectors, (B, L, D) last token states


def check_onnx_spec(spec: str) -> str:
    """The normalised spec of a text encoder that can run as an ONNX graph; MlctError else."""
    name = spec.strip().lower() if isinstance(spec, str) else spec
    if name not in ONNX_SPECS:
        raise MlctError(f"the onnx backend runs the bundled MiniLM text encoders "
                        f"({', '.join(ONNX_SPECS)}); this model uses {spec!r}")
    return name


def write_minilm_graph(spec: str, path: str | os.PathLike, fused: bool = True) -> Path:
    """Write the network of text encoder `spec` (one of MINILM_SPECS) to path.

    fused: with each layer's attention, skip layer norms and bias-GELUs as ONNX Runtime's own
    operators (com.microsoft Attention, SkipLayerNormalization, BiasGelu; its transformer
    optimizer): 71 operators instead of 326 after its session optimizations, ~0.2-0.7 ms off a
    sentence on 2 threads (docs/performance.md). Off, the graph
    keeps standard ONNX operators only, for runtimes without those (the browser page's)."""
    from mlct.text.minilm import MiniLMEncoder

    encoder = MiniLMEncoder(bundled_minilm_path(), name=check_onnx_spec(spec))
    encoder.model.explicit_attention = fused  # the pattern the optimizer recognises
    ids, mask = encoder._pad([[101, 1037, 2711, 7365, 102], [101, 102]])  # two lengths: padding
    tokens = {0: "batch", 1: "tokens"}
    path = export_graph(encoder.network, (ids, mask), path, INPUTS, OUTPUTS,
                        {"ids": tokens, "mask": tokens, "embedding": {0: "batch"},
                         "states": tokens})
    if fused:
        _fuse_transformer_operators(path, encoder.model.config)
    return path


def _fuse_transformer_operators(path: Path, config: Any) -> None:
    """Rewrite the graph at path with ONNX Runtime's fused transformer operators, in place;
    left as it is when the optimizer cannot match every layer's attention (another
    onnxruntime), since the unfused graph computes the same."""
    import logging

    from onnxruntime.transformers.optimizer import optimize_model

    quiet = logging.getLogger("onnxruntime.transformers")  # it logs every fusion it tries
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        model = optimize_model(str(path), model_type="bert",
                               num_heads=config.num_attention_heads,
                               hidden_size=config.hidden_size, opt_level=0)
    finally:
        quiet.setLevel(level)
    if model.get_fused_operator_statistics().get("Attention", 0) == config.num_hidden_layers:
        model.save_model_to_file(str(path))


class OnnxMiniLMEncoder(TextEncoder):
    """The MiniLM text encoder (minilm.MiniLMEncoder's embeddings) with its network an ONNX
    graph (write_minilm_graph) run on the CPU; numpy throughout (encode_numpy), encode wraps
    that in a torch tensor for the callers that want one."""

    def __init__(self, graph: str | os.PathLike, spec: str, threads: int | None = None,
                 batch_size: int = 256) -> None:
        self.name = check_onnx_spec(spec)
        self.path = bundled_minilm_path()
        self.tokenizer, self.max_length, config = load_tokenizer(self.path)
        self.batch_size = batch_size
        self.token_slots = token_slots_of(self.name)
        self.dim = (1 + self.token_slots) * config.hidden_size
        self.graph = Path(graph)
        self.threads = int(threads or default_threads())
        # None: spin within a run while the machine is idle beside it (onnx_io.spin_now); a
        # bool forces the choice (bench/paired_speed.py compares them)
        self.spinning: bool | None = None
        self._sessions: dict[bool, Any] = {}
        self._runs = 0
        self._session(self._spin())  # now: a graph ONNX Runtime cannot load is said at load

    @property
    def cache_key(self) -> str:
        if self.name.endswith(SIDES_SUFFIX):  # the contrast's captions follow the mirror rule
            return f"{self.name}@mirror{MIRROR_VERSION}"
        return self.name

    def _encode(self, texts: list[str]) -> Tensor:
        import torch

        return torch.from_numpy(self._encode_numpy(texts))

    def _encode_numpy(self, texts: list[str]) -> np.ndarray:
        if not self.name.endswith(SIDES_SUFFIX):
            return self._embed(texts)
        # the captions and the mirrors of those naming a side in one run (minilm.py's order)
        mirrors = [m for t in texts if (m := mirror_sides(t)) != t]
        both = self._embed(list(texts) + mirrors)
        return contrast_sides(texts, both[: len(texts)], lambda _: both[len(texts):])

    def _embed(self, texts: list[str]) -> np.ndarray:
        """The network's embeddings, pooled (and token states), before any side contrast:
        longest first in batches (minilm.MiniLMEncoder._embed)."""
        encodings = self.tokenizer.encode_batch(texts)
        order = sorted(range(len(texts)), key=lambda i: -len(encodings[i].ids))
        out = np.empty((len(texts), self.dim), np.float32)
        for start in range(0, len(order), self.batch_size):
            batch = order[start : start + self.batch_size]
            ids, mask = _pad([encodings[i].ids for i in batch])
            pooled, states = self._run(ids, mask)  # (b, D), (b, L, D)
            out[batch] = (_with_tokens(pooled, states, mask, self.token_slots)
                          if self.token_slots else pooled)
        return out

    @property
    def session(self) -> Any:
        """The graph's session for the next run: its threads spin between operators within
        the run and stop with it while the machine has idle CPUs for them, and sleep otherwise
        (a new sentence 3.04 against 3.70 ms sleeping on 2 quiet cores; 2x slower spinning
        beside other work). Each kind is made on first use, the second kind not before the
        second run: a one-off command's one sentence runs on the session made at load (another
        would cost ~40 ms), and a machine whose load changes pays a second copy of the weights
        (~100 MB) once."""
        spin = self._spin()
        if spin not in self._sessions and not self._runs:
            (spin,) = self._sessions
        return self._session(spin)

    def _spin(self) -> bool:
        return self.spinning if self.spinning is not None else spin_now(self.threads)

    def _session(self, spin: bool) -> Any:
        if spin not in self._sessions:
            self._sessions[spin] = session(self.graph, self.threads, spin)
        return self._sessions[spin]

    def _run(self, ids: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        chosen = self.session
        self._runs += 1
        pooled, states = chosen.run(list(OUTPUTS), {"ids": ids, "mask": mask})
        return pooled, states


def _pad(ids: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Right-pad token ids to the batch's longest: (b, L) int64 ids and 0/1 mask."""
    longest = max(len(row) for row in ids)
    padded = np.zeros((len(ids), longest), np.int64)
    mask = np.zeros((len(ids), longest), np.int64)
    for i, row in enumerate(ids):
        padded[i, : len(row)] = row
        mask[i, : len(row)] = 1
    return padded, mask


def _with_tokens(pooled: np.ndarray, states: np.ndarray, mask: np.ndarray,
                 slots: int) -> np.ndarray:
    """(b, (1 + K) D): the pooled vector, then the first K token states, zero-padded
    (minilm.MiniLMEncoder._with_tokens)."""
    out = np.zeros((states.shape[0], slots, states.shape[-1]), np.float32)
    kept = min(slots, states.shape[1])
    out[:, :kept] = states[:, :kept] * mask[:, :kept, None].astype(np.float32)
    return np.concatenate([pooled, out.reshape(len(out), -1)], axis=1)
