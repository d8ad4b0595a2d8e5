"""The text-motion matching evaluator: text and motion co-embeddings for the standard metrics.

Facts from EricGuo5513/text-to-motion networks/evaluator_wrapper.py, options/ and
networks/trainers.py (TextMotionMatchTrainer):
- sizes: word 300, POS 15, movement hidden 512 and latent 512, text hidden 512, motion hidden
  1024, co-embedding 512, unit_length 4;
- the movement encoder sees the features without the last 4 (the foot contacts), the motion
  encoder m_lens // unit_length movement steps;
- motions are normalized by the evaluator's own mean/std (the `meta/` of the comparison model),
  and padded with zeros after normalization by every loader of the protocol;
- the checkpoint `{dataset}/text_mot_match/model/finest.tar` is a torch pickle with the state
  dicts 'text_encoder', 'movement_encoder', 'motion_encoder' (and optimizer states, 'epoch',
  'iter'); the reference loader also reads 'epoch'.

Unlike the reference, embeddings come back in input order (it returns them sorted by motion
length). The movement convolutions see up to 2 frames past a motion's last whole movement step,
and their zero-input activations are not zero (biases), so the reference's embedding of the
last step depends on the buffer it is given; the main protocol's loaders always give zero-padded
196-frame buffers. Here every motion is embedded that way (frames past m_len zeroed, buffer
zero-padded or cut to 196 frames), so an embedding depends on motion[:m_len] alone. (The
reference's MultiModality loader passes unpadded motions; its last step differs slightly.)
"""

from __future__ import annotations

from dataclasses import dataclass

import os
from pathlib import Path
from typing import Any, Mapping, Sequence, cast

import numpy as np
import torch
from torch import Tensor, nn
from torch.nn import functional as F

from mlct.data.dataset import MAX_MOTION_LENGTH
from mlct.errors import MlctError, first_line
from mlct.eval.judge.networks import MotionEncoderBiGRUCo, MovementConvEncoder, TextEncoderBiGRUCo
from mlct.eval.judge.word_vectors import POS_ENUMERATOR, WORD_DIM, WordVectorizer
from mlct.io import atomic_path

UNIT_LENGTH = 4  # frames per movement step (two stride-2 convolutions)
FOOT_CONTACT_DIMS = 4  # the last features, not seen by the movement encoder
MOVEMENT_HIDDEN = 512
MOVEMENT_LATENT = 512
TEXT_HIDDEN = 512
MOTION_HIDDEN = 1024
EMBEDDING_DIM = 512  # dim_coemb_hidden
NETWORK_KEYS = ("text_encoder", "movement_encoder", "motion_encoder")
CHECKPOINT_NAMES = ("finest.tar", "model/finest.tar", "text_mot_match/model/finest.tar")
PAD_TOKEN = "unk/OTHER"  # the reference pads token lists with it
FORMAT = "mlct-evaluator"


@dataclass(frozen=True)
class EvaluatorSizes:
    """Network widths; the defaults are the official evaluator's (checkpoints load strictly)."""

    word: int = WORD_DIM  # word vectors: GloVe's 300; a learned table may be narrower
    movement_hidden: int = MOVEMENT_HIDDEN
    movement_latent: int = MOVEMENT_LATENT
    text_hidden: int = TEXT_HIDDEN
    motion_hidden: int = MOTION_HIDDEN
    embedding: int = EMBEDDING_DIM  # dim_coemb_hidden


# Narrower widths for a small benchmark trained on a CPU: the motion GRU (hidden 1024 over 49
# steps) is 90% of the official size's training time, about 1.7 s a step on one core; at these
# widths a step takes about a tenth. Same networks, same protocol; not comparable across sizes.
COMPACT_SIZES = EvaluatorSizes(movement_hidden=256, movement_latent=256, text_hidden=256,
                               motion_hidden=256)
EVALUATOR_SIZES = {"official": EvaluatorSizes(), "compact": COMPACT_SIZES}


def build_networks(feature_dim: int, sizes: EvaluatorSizes = EvaluatorSizes()
                   ) -> dict[str, nn.Module]:
    """Fresh (randomly initialized) evaluator networks for `feature_dim`-d motion features."""
    if feature_dim <= FOOT_CONTACT_DIMS:
        raise MlctError(f"feature_dim must exceed {FOOT_CONTACT_DIMS}, got {feature_dim}")
    return {
        "text_encoder": TextEncoderBiGRUCo(sizes.word, len(POS_ENUMERATOR), sizes.text_hidden,
                                           sizes.embedding),
        "movement_encoder": MovementConvEncoder(feature_dim - FOOT_CONTACT_DIMS,
                                                sizes.movement_hidden, sizes.movement_latent),
        "motion_encoder": MotionEncoderBiGRUCo(sizes.movement_latent, sizes.motion_hidden,
                                               sizes.embedding),
    }


def _stat(value: np.ndarray | Tensor, name: str, feature_dim: int) -> Tensor:
    if isinstance(value, Tensor):
        stat = value.detach().to("cpu", torch.float32)
    else:
        stat = torch.as_tensor(np.asarray(value, dtype=np.float32))
    if stat.shape != (feature_dim,):
        raise MlctError(f"evaluator {name} has shape {tuple(stat.shape)}, "
                        f"expected ({feature_dim},)")
    if not torch.isfinite(stat).all():
        raise MlctError(f"evaluator {name} is not finite everywhere")
    return stat


def _resolve_checkpoint(path: str | os.PathLike) -> Path:
    """A finest.tar file, or a directory holding one at a standard place."""
    path = Path(path)
    if path.is_file():
        return path
    if path.is_dir():
        for name in CHECKPOINT_NAMES:
            if (path / name).is_file():
                return path / name
    raise MlctError(f"{path}: no evaluator checkpoint (a file, or a directory with "
                    f"{', '.join(CHECKPOINT_NAMES)})")


def load_state_checked(module: nn.Module, state: Any, name: str, source: Path) -> None:
    """load_state_dict(strict=True) after checking every key and shape, failing in one line."""
    if not isinstance(state, Mapping):
        raise MlctError(f"{source}: '{name}' is not a state dict")
    expected = module.state_dict()
    for key, value in expected.items():
        if key not in state:
            raise MlctError(f"{source}: key {name}.{key} is missing")
        got = state[key]
        if not isinstance(got, Tensor):
            raise MlctError(f"{source}: {name}.{key} is not a tensor")
        if got.shape != value.shape:
            hint = ""
            if name == "movement_encoder" and key == "main.0.weight" and got.ndim == 3:
                hint = f" (a checkpoint for {got.shape[1] + FOOT_CONTACT_DIMS}-d features?)"
            raise MlctError(f"{source}: {name}.{key} has shape {tuple(got.shape)}, "
                            f"expected {tuple(value.shape)}{hint}")
    extra = sorted(set(state) - set(expected))
    if extra:
        more = f" (and {len(extra) - 1} more)" if len(extra) > 1 else ""
        raise MlctError(f"{source}: unexpected key {name}.{extra[0]}{more}")
    module.load_state_dict(state, strict=True)


class Evaluator:
    """The three frozen networks, the evaluator's mean/std and its word vectors."""

    def __init__(self, networks: Mapping[str, nn.Module], mean: np.ndarray | Tensor,
                 std: np.ndarray | Tensor, vectorizer: WordVectorizer | None = None,
                 epoch: int = 0) -> None:
        missing = [key for key in NETWORK_KEYS if key not in networks]
        if missing:
            raise MlctError(f"evaluator networks lack {', '.join(missing)}")
        self.text_encoder = cast(TextEncoderBiGRUCo, networks["text_encoder"])
        self.movement_encoder = cast(MovementConvEncoder, networks["movement_encoder"])
        self.motion_encoder = cast(MotionEncoderBiGRUCo, networks["motion_encoder"])
        self.feature_dim = self.movement_encoder.main[0].in_channels + FOOT_CONTACT_DIMS
        self.mean = _stat(mean, "mean", self.feature_dim)
        self.std = _stat(std, "std", self.feature_dim)
        if not (self.std > 0).all():
            raise MlctError("evaluator std must be > 0 everywhere (normalization divides by it)")
        self.vectorizer = vectorizer
        self.epoch = epoch
        for module in self.networks().values():
            module.eval()  # dropout off: the evaluator is a fixed measuring device

    def networks(self) -> dict[str, nn.Module]:
        """The three networks under their checkpoint keys."""
        return {"text_encoder": self.text_encoder, "movement_encoder": self.movement_encoder,
                "motion_encoder": self.motion_encoder}

    @classmethod
    def create(cls, feature_dim: int, mean: np.ndarray | Tensor | None = None,
               std: np.ndarray | Tensor | None = None,
               vectorizer: WordVectorizer | None = None) -> Evaluator:
        """Randomly initialized networks (to train one, or in tests); mean 0 / std 1 by default."""
        mean = np.zeros(feature_dim, np.float32) if mean is None else mean
        std = np.ones(feature_dim, np.float32) if std is None else std
        return cls(build_networks(feature_dim), mean, std, vectorizer)

    @classmethod
    def load_official(cls, checkpoint: str | os.PathLike, glove_dir: str | os.PathLike | None,
                      mean: np.ndarray | Tensor | None = None,
                      std: np.ndarray | Tensor | None = None,
                      feature_dim: int | None = None) -> Evaluator:
        """Load a `finest.tar` (official, or written by `save`) with its mean/std and GloVe dir.

        mean/std default to those stored by `save`; feature_dim to len(mean) (263 HumanML3D,
        251 KIT). glove_dir None loads no word vectors (motion embeddings only).
        """
        source = _resolve_checkpoint(checkpoint)
        try:
            state = torch.load(source, map_location="cpu", weights_only=True)
        except Exception as error:  # noqa: BLE001 - any unreadable file gets the same one line
            raise MlctError(f"{source}: not a readable weights-only torch checkpoint "
                            f"({type(error).__name__}: {first_line(error, '')})") from None
        if not isinstance(state, Mapping):
            raise MlctError(f"{source}: expected a dict with {', '.join(NETWORK_KEYS)}")
        for key in NETWORK_KEYS:
            if key not in state:
                raise MlctError(f"{source}: key {key!r} is missing (expected "
                                f"{', '.join(NETWORK_KEYS)})")
        mean = state.get("mean") if mean is None else mean
        std = state.get("std") if std is None else std
        if mean is None or std is None:
            raise MlctError(f"{source}: holds no mean/std; pass the evaluator's mean and std "
                            f"(text-to-motion's checkpoints/<dataset>/Comp_v6_*/meta/*.npy)")
        if feature_dim is None:
            if np.ndim(mean) != 1:
                raise MlctError(f"evaluator mean must be a (D,) vector, got {np.ndim(mean)}-d")
            feature_dim = len(mean)
        networks = build_networks(feature_dim)
        for key, module in networks.items():
            load_state_checked(module, state[key], key, source)
        vectorizer = None if glove_dir is None else WordVectorizer(glove_dir)
        epoch = state.get("epoch", 0)
        return cls(networks, mean, std, vectorizer, epoch=epoch if isinstance(epoch, int) else 0)

    def save(self, path: str | os.PathLike) -> None:
        """Write a finest.tar-compatible dict: the three state dicts, epoch, plus mean/std."""
        state: dict[str, Any] = {
            key: {name: t.detach().cpu() for name, t in module.state_dict().items()}
            for key, module in self.networks().items()
        }
        # 'epoch' is read (printed) by the reference's build_models; mean/std make the file
        # self-describing for load_official.
        state.update(epoch=self.epoch, mean=self.mean.cpu(), std=self.std.cpu(),
                     feature_dim=self.feature_dim, unit_length=UNIT_LENGTH, format=FORMAT)
        with atomic_path(path) as tmp:
            torch.save(state, tmp)

    @property
    def device(self) -> torch.device:
        return self.text_encoder.hidden.device

    def to(self, device: torch.device | str) -> Evaluator:
        for module in self.networks().values():
            module.to(device)
        self.mean, self.std = self.mean.to(device), self.std.to(device)
        return self

    def normalize(self, motion: Tensor) -> Tensor:
        """Raw features (..., D) -> the evaluator's normalization (its own mean/std)."""
        mean = self.mean.to(motion.device, motion.dtype)
        return (motion - mean) / self.std.to(motion.device, motion.dtype)

    def tokens_to_tensors(self, token_lists: Sequence[Sequence[str]]) -> tuple[Tensor, Tensor]:
        """`word/POS` token lists -> word_embs (B, L, 300), pos_ohot (B, L, 15).

        Shorter lists are padded with unk/OTHER to the longest, as the reference pads.
        """
        if self.vectorizer is None:
            raise MlctError("this evaluator has no word vectors; load it with a GloVe directory")
        if not token_lists:
            raise MlctError("tokens_to_tensors needs at least one token list")
        length = max(len(tokens) for tokens in token_lists)
        words, pos = zip(*(self.vectorizer.encode(
            list(tokens) + [PAD_TOKEN] * (length - len(tokens))) for tokens in token_lists))
        return (torch.from_numpy(np.stack(words)).to(self.device),
                torch.from_numpy(np.stack(pos)).to(self.device))

    @torch.no_grad()
    def embed_text(self, word_embs: Tensor, pos_ohot: Tensor,
                   cap_lens: Tensor | Sequence[int]) -> Tensor:
        """(B, L, 300), (B, L, 15), (B,) token counts -> text embeddings (B, 512), input order."""
        lens = torch.as_tensor(cap_lens, dtype=torch.long).cpu()
        batch = word_embs.shape[0]
        if word_embs.ndim != 3 or word_embs.shape[:2] != pos_ohot.shape[:2]:
            raise MlctError(f"word_embs {tuple(word_embs.shape)} and pos_ohot "
                            f"{tuple(pos_ohot.shape)} must be (B, L, .) alike")
        length = word_embs.shape[1]
        if lens.shape != (batch,) or batch == 0 or lens.min() < 1 or lens.max() > length:
            raise MlctError(f"cap_lens must be (B,) in [1, {word_embs.shape[1]}], got "
                            f"{lens.tolist()}")
        device = self.device
        return self.text_encoder(word_embs.to(device, torch.float32),
                                 pos_ohot.to(device, torch.float32), lens)

    @torch.no_grad()
    def embed_motion(self, motions: Tensor, m_lens: Tensor | Sequence[int]) -> Tensor:
        """Motions normalized by the evaluator's stats (B, T, D), frame counts (B,) -> (B, 512).

        Each motion is seen as the protocol's loaders give it: motion[:m_len] then zeros, in a
        196-frame buffer; the GRU reads m_len // 4 whole movement steps, as the reference.
        """
        if motions.ndim != 3 or motions.shape[-1] != self.feature_dim:
            raise MlctError(f"motions must be (B, T, {self.feature_dim}), got "
                            f"{tuple(motions.shape)}")
        batch, frames = motions.shape[:2]
        lens = torch.as_tensor(m_lens, dtype=torch.long).cpu()
        high = min(frames, MAX_MOTION_LENGTH)
        if lens.shape != (batch,) or batch == 0 or lens.min() < UNIT_LENGTH or lens.max() > high:
            raise MlctError(f"m_lens must be (B,) in [{UNIT_LENGTH}, {high}] (the evaluator "
                            f"reads at most {MAX_MOTION_LENGTH} frames), got {lens.tolist()}")
        device = self.device
        # The 196-frame buffer: frames past m_len are zero, so cutting or padding loses nothing.
        x = motions[:, :MAX_MOTION_LENGTH].to(device, torch.float32)
        x = F.pad(x, (0, 0, 0, MAX_MOTION_LENGTH - x.shape[1]))  # (B, 196, D)
        valid = torch.arange(MAX_MOTION_LENGTH, device=device)[None, :] < lens.to(device)[:, None]
        x = x[..., :-FOOT_CONTACT_DIMS] * valid[..., None]  # (B, 196, D - 4), contacts dropped
        movements = self.movement_encoder(x)  # (B, 49, 512)
        return self.motion_encoder(movements, lens // UNIT_LENGTH)
