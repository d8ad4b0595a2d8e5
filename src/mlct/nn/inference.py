"""Sampling-time layers: the trained networks' own weights, run with fewer and cheaper kernels.

Why: at batch 1 the denoiser multiplies 4 tokens by every weight matrix, so a sample is a chain
of skinny matrix products that stream the weights from memory, plus small-op overhead. Measured
on a 2-core EPYC (docs/performance.md):
- a plain CPU matmul re-lays-out the weight on every call; kept in oneDNN's blocked layout
  (packed once, as torch.compile's CPU freezing does) the product chain of the paper-size
  denoiser runs 1.8x faster in fp32 and 3x faster with bfloat16 weights;
- PyTorch's fused encoder-layer kernel is slower than scaled-dot-product attention plus plain
  products when a padding mask is given (the decoder's case);
- a Conv1d over (B, C, T) in PyTorch's default layout runs at half the GEMM peak on oneDNN;
  the same convolution over channels-last frames (C the fastest axis) runs at the peak
  (a 128 -> 128, kernel-3 conv of 64 x 200 frames, one thread of this repository's Intel host:
  13.7 ms against 6.9; docs/performance.md).

`for_inference(module, dtype)` swaps, in place, every ``nn.TransformerEncoderLayer`` for a
`FastEncoderLayer`, every ``nn.Linear`` for a `FastLinear` and, with prepack (the CPU kernels'
path; an ONNX export passes prepack=False), every stack of Conv1d / GELU / nearest Upsample
layers for a `ChannelsLastConvs`, all holding the same weights
(shared in fp32, converted once otherwise). Activations, layer norms and softmax stay in the
input's dtype; with bfloat16 weights only the products' inputs are rounded. The swapped module
computes the same function (tests/test_inference_equivalence.py) but cannot be trained.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from mlct import cpu_features
from mlct.cpu_features import WEIGHT_DTYPES, weight_dtype  # noqa: F401  (where callers find it)



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


def _fused_conv() -> object | None:
    """oneDNN's convolution with a fused pointwise op (torch.compile's CPU path uses it), or
    None where this torch has no such op."""
    try:
        return torch.ops.mkldnn._convolution_pointwise
    except (AttributeError, RuntimeError):
        return None


class ChannelsLastConvs(nn.Module):
    """An nn.Sequential of Conv1d, GELU and nearest nn.Upsample layers (the conv autoencoder's
    stacks), its function with the weights in `dtype`. On the CPU the frames are laid out
    channels-last once, as (B, C, 1, T), and every layer runs on that layout: a convolution of
    height 1 with the GELU after it fused in (oneDNN's post-op), a nearest upsampling along T.
    The output is (B, C, T) with channels-last strides, which a caller reads as any (B, C, T)
    tensor and transposes to (B, T, C) for free. Off the CPU, or where a gradient must flow
    back through it: the layers as they are."""

    def __init__(self, chain: nn.Sequential, dtype: torch.dtype) -> None:
        super().__init__()
        if not is_conv_chain(chain):
            raise ValueError("ChannelsLastConvs takes a Sequential of ungrouped, zero- and "
                             "number-padded Conv1d, GELU and nearest Upsample layers")
        # steps: ("conv", index, stride, padding, dilation, GELU after it: approximate or None)
        # and ("gelu", approximate) for a GELU that follows no convolution, ("up", scale)
        self.plan: list[tuple] = []
        weights, biases = [], []
        for layer in chain:
            if isinstance(layer, nn.Conv1d):
                self.plan.append(("conv", len(weights), layer.stride[0], layer.padding[0],
                                  layer.dilation[0], None))
                weights.append(nn.Parameter(layer.weight.detach().to(dtype), requires_grad=False))
                bias = (layer.weight.new_zeros(layer.out_channels) if layer.bias is None
                        else layer.bias.detach())  # a zero bias adds exactly nothing
                biases.append(nn.Parameter(bias.to(dtype), requires_grad=False))
            elif isinstance(layer, nn.GELU) and self.plan and self.plan[-1][0] == "conv" \
                    and self.plan[-1][5] is None:
                self.plan[-1] = (*self.plan[-1][:5], layer.approximate)
            elif isinstance(layer, nn.GELU):
                self.plan.append(("gelu", layer.approximate))
            else:
                self.plan.append(("up", float(layer.scale_factor)))
        self.weights, self.biases = nn.ParameterList(weights), nn.ParameterList(biases)
        self._cl: list[Tensor] | None = None  # the weights as (C_out, C_in, 1, k), channels-last

    def __getstate__(self) -> dict:
        return {**super().__getstate__(), "_cl": None}

    def forward(self, x: Tensor) -> Tensor:
        h = x.to(self.weights[0].dtype)
        # oneDNN's fused op has no backward: a gradient through the stack (decoder guidance,
        # control/) takes the layers as they are
        cpu = x.device.type == "cpu" and not (x.requires_grad and torch.is_grad_enabled())
        if cpu:
            if self._cl is None:
                self._cl = [w.unsqueeze(2).contiguous(memory_format=torch.channels_last)
                            for w in self.weights]
            h = h.unsqueeze(2).contiguous(memory_format=torch.channels_last)  # (B, C, 1, T)
        # oneDNN's op refuses bfloat16 on a CPU without its bf16 kernels (mlct.cpu_features):
        # there the plain convolution runs it
        fused = _fused_conv() if cpu and (h.dtype == torch.float32 or _onednn_bf16()) else None
        for step in self.plan:
            if step[0] == "conv":
                _, i, stride, padding, dilation, gelu = step
                bias = self.biases[i]
                if not cpu:
                    h = F.conv1d(h, self.weights[i], bias, stride, padding, dilation)
                elif fused is not None:
                    h = fused(h, self._cl[i], bias, [0, padding], [1, stride], [1, dilation],
                              1, "none" if gelu is None else "gelu", [],
                              "none" if gelu is None else gelu)
                    continue
                else:
                    h = F.conv2d(h, self._cl[i], bias, (1, stride), (0, padding), (1, dilation))
                if gelu is not None:
                    h = _gelu(h, gelu)
            elif step[0] == "gelu":
                h = _gelu(h, step[1])
            else:
                h = F.interpolate(h, scale_factor=(1.0, step[1]) if cpu else step[1],
                                  mode="nearest")
        return (h.squeeze(2) if cpu else h).to(x.dtype)


def _onednn_bf16() -> bool:
    return cpu_features.onednn_bf16()  # looked up when called: tests stand in another CPU


def _gelu(h: Tensor, approximate: str) -> Tensor:
    """GELU keeping h's layout; a 4-d channels-last h goes through its dense (B, 1, T, C) view:
    PyTorch's CPU GELU runs ~10x slower on the channels-last strides themselves."""
    if h.dim() == 4 and h.is_contiguous(memory_format=torch.channels_last):
        return F.gelu(h.permute(0, 2, 3, 1), approximate=approximate).permute(0, 3, 1, 2)
    return F.gelu(h, approximate=approximate)


def is_conv_chain(chain: nn.Module) -> bool:
    """Whether ChannelsLastConvs can run this module: an nn.Sequential of ungrouped, zero- and
    number-padded Conv1d layers (at least one), GELUs and nearest, scale-given Upsamples."""
    if not isinstance(chain, nn.Sequential) or len(chain) == 0:
        return False
    convs = 0
    for layer in chain:
        if isinstance(layer, nn.Conv1d):
            if (layer.groups != 1 or layer.padding_mode != "zeros"
                    or isinstance(layer.padding, str)):
                return False
            convs += 1
        elif isinstance(layer, nn.Upsample):
            scale = layer.scale_factor
            if layer.mode != "nearest" or layer.size is not None or not isinstance(
                    scale, (int, float)):
                return False
        elif not isinstance(layer, nn.GELU):
            return False
    return convs > 0


def for_inference(module: nn.Module, dtype: str | torch.dtype = "float32",
                  prepack: bool = True, channels_last: bool = True) -> nn.Module:
    """Swap `module`'s encoder layers, linears and conv stacks for the fast ones, in place;
    returns it, in eval mode without gradients. bfloat16 converts the swapped weights once. Call
    it after moving the module to its device; prepack=False keeps plain products and the
    Conv1d layers (for comparisons and the ONNX export), channels_last=False the Conv1d layers
    alone."""
    dt = weight_dtype(dtype)
    module.eval().requires_grad_(False)
    for name, child in module.named_children():
        if isinstance(child, nn.TransformerEncoderLayer):
            setattr(module, name, FastEncoderLayer(child, dt, prepack))
        elif isinstance(child, nn.Linear):
            setattr(module, name, FastLinear(child.weight, child.bias, dt, prepack))
        elif prepack and channels_last and is_conv_chain(child):
            setattr(module, name, ChannelsLastConvs(child, dt))
        else:
            for_inference(child, dt, prepack, channels_last)
    return module
