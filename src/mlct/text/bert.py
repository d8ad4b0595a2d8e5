"""A BERT text encoder in plain torch, enough to run the bundled all-MiniLM-L6-v2.

Why not transformers: importing transformers and sentence-transformers costs seconds (they pull
in sklearn, scipy.stats and torch.distributed), most of `mlct generate`'s cold start, to run a
6-layer encoder that is a few dozen lines of torch. The submodules are named as in the Hugging
Face checkpoint ("encoder.layer.0.attention.self.query.weight", ...) so that its state_dict
loads as it is, with `strict=True` catching any mismatch.

Only what the bundled model uses is supported: absolute position embeddings, exact (erf) GELU,
post-LayerNorm layers, no pooler (sentence embeddings are mean-pooled by the caller).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from mlct.text.minilm_files import BertConfig  # (sizes only: read without torch)


class _Uninitialized(nn.Module):
    """A weight (and bias) left uninitialised: every value comes from the checkpoint.

    nn.Embedding's and nn.Linear's random init would cost 0.1 s of the cold start (the word
    table alone is 30522 x 384), to be overwritten at once; a strict load leaves none unset."""

    def __init__(self, *shape: int, bias: bool) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.empty(*shape))
        self.bias = nn.Parameter(torch.empty(shape[0])) if bias else None


class _Table(_Uninitialized):
    """An embedding table (rows, width)."""

    def __init__(self, rows: int, width: int) -> None:
        super().__init__(rows, width, bias=False)

    def forward(self, ids: Tensor) -> Tensor:
        return F.embedding(ids, self.weight)


class _Dense(_Uninitialized):
    """A linear layer (width_in -> width_out) with bias."""

    def __init__(self, width_in: int, width_out: int) -> None:
        super().__init__(width_out, width_in, bias=True)

    def forward(self, x: Tensor) -> Tensor:
        return F.linear(x, self.weight, self.bias)


class _Embeddings(nn.Module):
    """Word + position + token-type embeddings, then LayerNorm."""

    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.word_embeddings = _Table(c.vocab_size, c.hidden_size)
        self.position_embeddings = _Table(c.max_position_embeddings, c.hidden_size)
        self.token_type_embeddings = _Table(c.type_vocab_size, c.hidden_size)
        self.LayerNorm = nn.LayerNorm(c.hidden_size, eps=c.layer_norm_eps)

    def forward(self, ids: Tensor) -> Tensor:
        positions = torch.arange(ids.shape[1], device=ids.device)
        # A single sentence: every token has type 0.
        x = (self.word_embeddings(ids) + self.position_embeddings(positions)
             + self.token_type_embeddings.weight[0])
        return self.LayerNorm(x)


class _SelfAttention(nn.Module):
    """Multi-head scaled dot-product attention over the unpadded keys."""

    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.heads = c.num_attention_heads
        self.query = _Dense(c.hidden_size, c.hidden_size)
        self.key = _Dense(c.hidden_size, c.hidden_size)
        self.value = _Dense(c.hidden_size, c.hidden_size)

    def forward(self, x: Tensor, keep: Tensor) -> Tensor:
        """x (B, L, D), keep (B, 1, 1, L): bool, True where a key is a real token; or float,
        an additive bias (0 for a real token, -10000 for padding) for the attention written
        out (BertModel.explicit_attention)."""
        b, n, d = x.shape

        def split(t: Tensor) -> Tensor:  # (B, L, D) -> (B, H, L, D / H)
            return t.view(b, n, self.heads, d // self.heads).transpose(1, 2)

        if keep.dtype == torch.bool:
            out = F.scaled_dot_product_attention(split(self.query(x)), split(self.key(x)),
                                                 split(self.value(x)), attn_mask=keep)
        else:  # softmax(q k^T / sqrt(d_head) + bias) v, operator by operator
            scores = split(self.query(x)) @ split(self.key(x)).transpose(-1, -2)
            scores = scores / math.sqrt(d // self.heads) + keep
            out = scores.softmax(dim=-1) @ split(self.value(x))
        return out.transpose(1, 2).reshape(b, n, d)


class _AddNorm(nn.Module):
    """Project, add the residual, LayerNorm: the end of both halves of a post-LN layer."""

    def __init__(self, width_in: int, c: BertConfig) -> None:
        super().__init__()
        self.dense = _Dense(width_in, c.hidden_size)
        self.LayerNorm = nn.LayerNorm(c.hidden_size, eps=c.layer_norm_eps)

    def forward(self, x: Tensor, residual: Tensor) -> Tensor:
        return self.LayerNorm(self.dense(x) + residual)


class _Attention(nn.Module):
    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.self = _SelfAttention(c)  # the checkpoint's name ("attention.self.query")
        self.output = _AddNorm(c.hidden_size, c)

    def forward(self, x: Tensor, keep: Tensor) -> Tensor:
        return self.output(self.self(x, keep), x)


class _Intermediate(nn.Module):
    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.dense = _Dense(c.hidden_size, c.intermediate_size)

    def forward(self, x: Tensor) -> Tensor:
        return F.gelu(self.dense(x))  # exact GELU: config "gelu"


class _Layer(nn.Module):
    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.attention = _Attention(c)
        self.intermediate = _Intermediate(c)
        self.output = _AddNorm(c.intermediate_size, c)

    def forward(self, x: Tensor, keep: Tensor) -> Tensor:
        x = self.attention(x, keep)
        return self.output(self.intermediate(x), x)


class _Layers(nn.Module):
    def __init__(self, c: BertConfig) -> None:
        super().__init__()
        self.layer = nn.ModuleList(_Layer(c) for _ in range(c.num_hidden_layers))


class BertModel(nn.Module):
    """BERT's encoder: token ids (B, L) and mask (B, L) -> last hidden states (B, L, D).

    Built uninitialised: load_checkpoint must run before it is used."""

    # Checkpoint entries this module has no use for: the [CLS] pooler (mean pooling is used
    # instead) and the position-id buffer (positions are always 0..L-1 here).
    UNUSED_PREFIXES = ("pooler.", "embeddings.position_ids")

    def __init__(self, config: BertConfig) -> None:
        super().__init__()
        self.config = config
        self.embeddings = _Embeddings(config)
        self.encoder = _Layers(config)
        # The attention as separate operators with an additive padding mask, the form ONNX
        # Runtime's transformer optimizer recognises and fuses into one Attention operator per
        # layer (text/minilm_onnx.py); the same function as scaled_dot_product_attention's
        # up to float rounding. Off, torch runs its fused kernel.
        self.explicit_attention = False

    def forward(self, ids: Tensor, mask: Tensor) -> Tensor:
        if ids.shape[1] > self.config.max_position_embeddings:
            raise ValueError(f"{ids.shape[1]} tokens; the model has "
                             f"{self.config.max_position_embeddings} positions")
        keep = mask.bool()[:, None, None, :]  # broadcast over heads and queries
        if self.explicit_attention:  # -10000 for a padding key: exp() of it is 0 in float32
            keep = (1.0 - keep.float()) * -10000.0
        x = self.embeddings(ids)
        for layer in self.encoder.layer:
            x = layer(x, keep)
        return x

    def load_checkpoint(self, tensors: dict[str, Tensor]) -> None:
        """Load a Hugging Face BertModel state_dict; RuntimeError if any weight is missing.

        The tensors are taken as they are (assign: no second copy of the weights)."""
        state = {k: v for k, v in tensors.items() if not k.startswith(self.UNUSED_PREFIXES)}
        self.load_state_dict(state, strict=True, assign=True)


def mean_pool(states: Tensor, mask: Tensor) -> Tensor:
    """The average of the real tokens' states (B, L, D) -> (B, D); padding does not count."""
    weights = mask.to(states.dtype).unsqueeze(-1)
    return (states * weights).sum(1) / weights.sum(1).clamp(min=1e-9)
