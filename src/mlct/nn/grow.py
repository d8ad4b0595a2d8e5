"""Growing a trained model's latent from n to more tokens (ours; `ae.grown_from`), either as
more tokens of the same pair or as an arm pair of its own (`ae.arm_tokens`; `add_arm_pair`).

Why: three 64-d tokens of the small conv autoencoder hold a clip's gait or an arm action laid
over it, not both (docs/training.md). Retraining a
wider latent from scratch also throws away every stage-2 step trained on the old one. Grown
instead, the old tokens keep their exact meaning (their encoder rows stay as they were) and the
decoder starts out ignoring the new ones (their input columns are zero), so the grown
autoencoder decodes exactly as before until training gives the new tokens something to carry,
and a stage 2 fine-tuned on it starts from a model that already makes the old tokens.

The tensors that depend on the token count:
- the conv autoencoder's ``to_tokens`` (rows: the encoder's outputs, ``groups`` x n x d, the VAE
  having a mean and a log-variance group) and ``from_tokens`` (columns: n x d inputs);
- the denoiser's ``pos`` (1 + n positions).
"""

from __future__ import annotations

import torch
from torch import Tensor

from mlct.errors import MlctError


def grow_tokens(old: dict[str, Tensor], fresh: dict[str, Tensor], old_n: int, new_n: int,
                latent_dim: int) -> dict[str, Tensor]:
    """`old`'s weights (a latent of old_n tokens) in the shapes of `fresh` (new_n tokens, newly
    initialised): new encoder rows and positions keep their fresh initialisation, new decoder
    input columns are zero. Every other tensor must have the same shape in both."""
    if new_n < old_n:
        raise MlctError(f"a latent can grow, not shrink: {old_n} -> {new_n} tokens")
    if set(old) != set(fresh):
        raise MlctError("the weights do not fit the grown network: different tensor names")
    d = latent_dim
    out = {}
    for key, new in fresh.items():
        was = old[key]
        if was.shape == new.shape:
            out[key] = was
        elif key.endswith("to_tokens.weight") or key.endswith("to_tokens.bias"):
            groups = was.shape[0] // (old_n * d)  # 1, or 2 for the VAE's mean and log-variance
            grown = new.detach().clone().view(groups, new_n, d, *new.shape[1:])
            grown[:, :old_n] = was.view(groups, old_n, d, *was.shape[1:])
            out[key] = grown.view(new.shape)
        elif key.endswith("from_tokens.weight"):
            grown = new.detach().clone()
            grown[:, : old_n * d] = was
            grown[:, old_n * d:] = 0.0  # the decoder ignores the new tokens until trained
            out[key] = grown
        elif key.endswith("pos") and was.shape[1] == 1 + old_n:
            grown = new.detach().clone()
            grown[:, : 1 + old_n] = was
            out[key] = grown
        else:
            raise MlctError(f"cannot grow {key} from {tuple(was.shape)} to {tuple(new.shape)}: "
                            f"growing the latent supports the conv autoencoder and the denoiser")
    return out


def old_token_rows(n_rows: int, old_n: int, new_n: int, latent_dim: int) -> Tensor:
    """Over a grown ``to_tokens`` tensor's n_rows outputs (groups x new_n x d): True on the rows
    of the first old_n tokens of each group, the ones a frozen encoder keeps."""
    groups = n_rows // (new_n * latent_dim)
    mask = torch.zeros(groups, new_n, latent_dim, dtype=torch.bool)
    mask[:, :old_n] = True
    return mask.view(n_rows)


# each arm-pair module and the body-pair module it mirrors (arm_pair_from_body copies them)
ARM_MODULES = {"arm_encoder": "encoder", "arm_to_tokens": "to_tokens",
               "arm_from_tokens": "from_tokens", "arm_decoder": "decoder"}
ARM_PREFIXES = tuple(f"{name}." for name in ARM_MODULES)


def add_arm_pair(old: dict[str, Tensor], fresh: dict[str, Tensor], body_columns: list[int],
                 arm_columns: list[int] | None = None) -> dict[str, Tensor]:
    """A conv autoencoder without an arm pair (`old`) in the shapes of one with it (`fresh`,
    its n old tokens now the body's): the encoder and the n tokens stay exactly as they were
    (so a stage 2 trained on them keeps its meaning), the decoder keeps its weights but draws
    only the body's columns (its last convolution's rows for them). The arm pair starts fresh,
    or, given `arm_columns` (`ae.arm_init=body`), as a copy of the body's pair restricted to the
    arms' columns (`arm_pair_from_body`)."""
    arm = {k for k in fresh if k.startswith(ARM_PREFIXES)}
    if any(k.startswith(ARM_PREFIXES) for k in old) or set(old) != set(fresh) - arm:
        raise MlctError("an arm pair is added to a conv autoencoder without one, whose other "
                        "weights keep their names")
    last = max(int(k.split(".")[1]) for k in fresh if k.startswith("decoder."))
    copied = (arm_pair_from_body(old, {k: fresh[k] for k in arm}, arm_columns, last)
              if arm_columns is not None else {})
    out = {}
    for key, new in fresh.items():
        if key in arm:
            out[key] = copied.get(key, new)
            continue
        was = old[key]
        if key in (f"decoder.{last}.weight", f"decoder.{last}.bias"):
            was = was[body_columns]
        if was.shape != new.shape:
            raise MlctError(f"cannot add an arm pair: {key} is {tuple(was.shape)}, the network "
                            f"wants {tuple(new.shape)} (keep ae.channels and the body's tokens)")
        out[key] = was
    return out


def arm_pair_from_body(old: dict[str, Tensor], arm: dict[str, Tensor], arm_columns: list[int],
                       last: int) -> dict[str, Tensor]:
    """The arm pair's weights (`arm`, fresh, for their shapes) as a copy of the old pair's,
    restricted to the arms: the encoder's first convolution keeps its input channels of the arm
    columns and of the validity mask (its last input), the decoder's last convolution its rows
    of the arm columns; every other tensor is the old one as it is.

    Why: an arm pair trained from fresh weights learnt to hold an arm's pose but drew no
    oscillation in 8,000 steps, not even a one-action clap's (docs/training.md); the old pair
    already draws claps and waves, so a copy of
    it restricted to the arms starts where those are drawn. Needs ae.arm_channels equal to
    ae.channels and as many arm tokens as the old latent has."""
    stem = old["encoder.0.weight"]  # (channels, features + 1, kernel): the mask is the last input
    inputs = torch.tensor([*arm_columns, stem.shape[1] - 1])
    out = {}
    for key, new in arm.items():
        module, rest = key.split(".", 1)
        source = f"{ARM_MODULES[module]}.{rest}"
        was = old[source]
        if source == "encoder.0.weight":
            was = was.index_select(1, inputs)
        elif source in (f"decoder.{last}.weight", f"decoder.{last}.bias"):
            was = was[arm_columns]
        if was.shape != new.shape:
            raise MlctError(f"cannot start the arm pair from the body's: {key} would be "
                            f"{tuple(was.shape)}, the network wants {tuple(new.shape)} (set "
                            f"ae.arm_channels to ae.channels and as many arm tokens as the model "
                            f"has)")
        out[key] = was.clone()
    return out
