"""Sampling-time layers: the trained networks' own weights, run with fewer and cheaper kernels.

Why: at batch 1 the denoiser multiplies 4 tokens by every weight matrix, so a sample is a chain
of skinny matrix products that stream the weights from memory, plus small-op overhead. Measured
on a 2-core EPYC (docs/performance.md):
- a plain CPU matmul re-lays-out the weight on every call; kept in oneDNN's blocked layout
  (packed once, as torch.compile's CPU freezing does) the product chain of the paper-size
  denoiser runs 1.8x faster in fp32 and 3x faster with bfloat16 weights;
- PyTorch's fused encoder-layer kernel is slower than scaled-dot-product attention plus plain
  products when a padding mask is given (the decoder's case).

`for_inference(module, dtype)` swaps, in place, every ``nn.TransformerEncoderLayer`` for a
`FastEncoderLayer` and every ``nn.Linear`` for a `FastLinear`, both holding the same weights
(shared in fp32, converted once otherwise). Activations, layer norms and softmax stay in the
input's dtype; with bfloat16 weights only the products' inputs are rounded. The swapped module
computes the same function (tests/test_inference_equivalence.py) but cannot be trained.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

WEIGHT_DTYPES = {"float32": torch.float32, "bfloat16": torch.bfloat16}


def weight_dtype(name: str | torch.dtype) -> torch.dtype:
    """The torch dtype for a weight-precision name; ValueError naming the choices otherwise."""
    if isinstance(name, torch.dtype) and name in WEIGHT_DTYPES.values():
        return name
    if isinstance(name, str) and name in WEIGHT_DTYPES:
        return WEIGHT_DTYPES[name]
    raise ValueError(f"unknown weight dtype {name!r}; choose one of {', '.join(WEIGHT_DTYPES)}")


def _onednn_layout(weight: Tensor) -> Tensor | None:
    """The weight in oneDNN's blocked layout, or None off the CPU or without oneDNN."""
    if weight.device.type != "cpu" or not torch.backends.mkldnn.is_available():
        return None
    try:  # an internal op (torch.compile's CPU path uses it); absent -> plain products
        return torch.ops.mkldnn._reorder_linear_weight(weight.detach(), None)
    except (AttributeError, RuntimeError):
        return None


class FastLinear(nn.Module):
    """y = x W^T + b with W stored in `dtype`; the product runs in that dtype, y has x's dtype.
    prepack: on the CPU, multiply with a oneDNN-blocked copy of W, made on the first call."""

    def __init__(self, weight: Tensor, bias: Tensor | None, dtype: torch.dtype,
                 prepack: bool = True) -> None:
        super().__init__()
        self.weight = nn.Parameter(weight.detach().to(dtype), requires_grad=False)
        self.bias = None if bias is None else nn.Parameter(bias.detach().to(dtype),
                                                             requires_grad=False)
        self.prepack = prepack
        self._packed: Tensor | None = None  # an opaque tensor: kept out of state_dict and copies

    def __getstate__(self) -> dict:
        return {**super().__getstate__(), "_packed": None}  # deepcopy cannot copy it; re-made

    def forward(self, x: Tensor) -> Tensor:
        xw = x.to(self.weight.dtype)
        cpu = x.device.type == "cpu"
        if self.prepack and cpu and self._packed is None:
            self._packed = _onednn_layout(self.weight)
            self.prepack = self._packed is not None  # cannot here: plain products from now on
        if cpu and self._packed is not None:
            y = torch.ops.mkldnn._linear_pointwise(xw, self._packed, self.bias, "none", [], "")
        else:
            y = F.linear(xw, self.weight, self.bias)
        return y.to(x.dtype)


class FastEncoderLayer(nn.Module):
    """The eval-mode function of a post-norm, batch-first ``nn.TransformerEncoderLayer``:
    x = LN1(x + MHA(x)); x = LN2(x + W2 act(W1 x)), attention by scaled_dot_product_attention."""

    def __init__(self, layer: nn.TransformerEncoderLayer, dtype: torch.dtype,
                 prepack: bool = True) -> None:
        super().__init__()
        attn = layer.self_attn
        if layer.norm_first or not attn.batch_first or not attn._qkv_same_embed_dim:
            raise ValueError("FastEncoderLayer takes post-norm, batch-first self-attention layers")
        self.heads = attn.num_heads
        self.qkv = FastLinear(attn.in_proj_weight, attn.in_proj_bias, dtype, prepack)  # d -> 3d
        self.out = FastLinear(attn.out_proj.weight, attn.out_proj.bias, dtype, prepack)
        self.linear1 = FastLinear(layer.linear1.weight, layer.linear1.bias, dtype, prepack)
        self.linear2 = FastLinear(layer.linear2.weight, layer.linear2.bias, dtype, prepack)
        self.norm1, self.norm2 = layer.norm1, layer.norm2
        self.activation = layer.activation

    def forward(self, x: Tensor, src_key_padding_mask: Tensor | None = None) -> Tensor:
        """x (B, S, d), src_key_padding_mask (B, S) bool True = pad -> (B, S, d)."""
        b, s, d = x.shape
        q, k, v = self.qkv(x).view(b, s, 3, self.heads, d // self.heads).permute(2, 0, 3, 1, 4)
        keep = None if src_key_padding_mask is None else ~src_key_padding_mask[:, None, None, :]
        a = F.scaled_dot_product_attention(q, k, v, attn_mask=keep)  # (B, h, S, d/h)
        x = self.norm1(x + self.out(a.transpose(1, 2).reshape(b, s, d)))
        return self.norm2(x + self.linear2(self.activation(self.linear1(x))))


def for_inference(module: nn.Module, dtype: str | torch.dtype = "float32",
                  prepack: bool = True) -> nn.Module:
    """Swap `module`'s encoder layers and linears for the fast ones, in place; returns it, in
    eval mode without gradients. bfloat16 converts the swapped weights once. Call it after
    moving the module to its device; prepack=False keeps plain products (for comparisons)."""
    dt = weight_dtype(dtype)
    module.eval().requires_grad_(False)
    for name, child in module.named_children():
        if isinstance(child, nn.TransformerEncoderLayer):
            setattr(module, name, FastEncoderLayer(child, dt, prepack))
        elif isinstance(child, nn.Linear):
            setattr(module, name, FastLinear(child.weight, child.bias, dt, prepack))
        else:
            for_inference(child, dt, prepack)
    return module
