"""A conv autoencoder's decoders cut to fewer channels (ours; `ae.decoder_init: prune`).

Why: at batch 1 the decoder's time is its channels (docs/performance.md). A 64/64 decoder trained
from fresh weights on the bundle's frozen encoder
reached 0.862 of the read-outs against the wide one's 0.955 in 15,500 steps, and never drew
the stretch's side lean (0.002 rad against 0.25). Started instead as the wide decoder with its
least important channels removed, it begins from a network that already draws every family,
only less exactly, and training has that gap to close rather than the whole decoder.

Which channels stay: for every hidden layer, the channels with the largest product of their
incoming weights' norm (what the layer writes into the channel) and their outgoing weights'
norm (how much the next layer reads from it), the filter-norm criterion of Li et al., "Pruning
Filters for Efficient ConvNets" (2017), taken both ways because a channel matters only if it
is both written and read. The decoder has no residual path, so each layer chooses its own set.

The decoder (nn/conv_autoencoder.py): ``from_tokens`` (a Linear to channels x coarse values,
row c * coarse + j being channel c at grid cell j), then 1-D convolutions (out, in, kernel)
between upsamplings and GELUs; the last convolution's outputs are the features and all stay.
"""

from __future__ import annotations

from torch import Tensor

from mlct.errors import MlctError

DECODERS = (("from_tokens", "decoder"), ("arm_from_tokens", "arm_decoder"))


def narrow_decoders(old: dict[str, Tensor], fresh: dict[str, Tensor]) -> dict[str, Tensor]:
    """The decoders of `old` (a conv autoencoder's state dict) cut to the widths of `fresh` (the
    narrower network's own state dict, for its shapes); every other tensor is fresh's. A decoder
    of the same width is copied as it is."""
    out = dict(fresh)
    for linear, convs in DECODERS:
        if f"{linear}.weight" not in fresh:
            continue
        if f"{linear}.weight" not in old:
            raise MlctError(f"cannot narrow {convs}: the model has none")
        out.update(_narrow_one(old, fresh, linear, convs))
    return out


def _conv_keys(state: dict[str, Tensor], convs: str) -> list[str]:
    """The convolutions of one decoder stack, in order (their Sequential index)."""
    index = sorted(int(k.split(".")[1]) for k in state
                   if k.startswith(f"{convs}.") and k.endswith(".weight"))
    return [f"{convs}.{i}" for i in index]


def _narrow_one(old: dict[str, Tensor], fresh: dict[str, Tensor], linear: str, convs: str
                ) -> dict[str, Tensor]:
    layers = _conv_keys(old, convs)
    if layers != _conv_keys(fresh, convs):
        raise MlctError(f"cannot narrow {convs}: the networks' layers differ")
    wide = old[f"{layers[0]}.weight"].shape[1]
    width = fresh[f"{layers[0]}.weight"].shape[1]
    if width > wide:
        raise MlctError(f"cannot narrow {convs} from {wide} to {width} channels: it would grow")
    cells = old[f"{linear}.weight"].shape[0] // wide
    if cells * width != fresh[f"{linear}.weight"].shape[0]:
        raise MlctError(f"cannot narrow {linear}: its grid differs")

    # channel c of the grid map is its rows c * cells ... (c + 1) * cells - 1
    grid_w = old[f"{linear}.weight"].reshape(wide, cells, -1)
    grid_b = old[f"{linear}.bias"].reshape(wide, cells)
    kept = _strongest(grid_w.flatten(1).norm(dim=1), old[f"{layers[0]}.weight"], width)
    out = {f"{linear}.weight": grid_w[kept].reshape(width * cells, -1).clone(),
           f"{linear}.bias": grid_b[kept].reshape(-1).clone()}
    for i, layer in enumerate(layers):
        weight, bias = old[f"{layer}.weight"][:, kept], old[f"{layer}.bias"]
        if i + 1 < len(layers):  # a hidden layer: keep its strongest outputs
            outputs = _strongest(weight.flatten(1).norm(dim=1), old[f"{layers[i + 1]}.weight"],
                                 width)
            weight, bias = weight[outputs], bias[outputs]
            kept = outputs
        out[f"{layer}.weight"], out[f"{layer}.bias"] = weight.clone(), bias.clone()
    for key, value in out.items():
        if value.shape != fresh[key].shape:
            raise MlctError(f"cannot narrow {key}: {tuple(value.shape)} against the network's "
                            f"{tuple(fresh[key].shape)}")
    return out


def _strongest(incoming: Tensor, next_weight: Tensor, width: int) -> Tensor:
    """The `width` channels with the largest incoming x outgoing weight norms, in their order."""
    outgoing = next_weight.transpose(0, 1).flatten(1).norm(dim=1)  # (channels,)
    return (incoming * outgoing).topk(width).indices.sort().values
