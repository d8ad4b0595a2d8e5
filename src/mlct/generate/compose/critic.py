"""The model folder's critic (critic.safetensors) and best-of-N sampling with it.

A consistency model samples a motion in a few steps, so sampling N for a prompt costs one batch.
Their latents differ by seed, and for a given prompt some do what it says and some do not (on
the benchmark's test captions, 84 % of one-action motions pass their read-out checks with one
sample, 92 % with the best of eight chosen by the read-outs themselves). The critic
(nn/critic.py, trained by `mlct train critic` on the training split only) scores each latent
against the text and the pipeline decodes one of the best: `candidates` per prompt, the
model's default when it has a critic, 1 (plain sampling) when it does not.

Which one: the first candidate, in seed order, whose score is within `margin` of the best
(Critic.pick). The best itself pulls every seed of a prompt to the one motion the critic likes
most, so five seeds gave five copies; the seed's own sample is kept whenever the critic rates it
nearly as well, and a poor one is still replaced. On the bundled model a margin of 0.05 keeps
the benchmark's read-outs and doubles the seeds' spread (docs/model_card.md); 0 is the best of N.

    MODEL_DIR/critic.safetensors   the critic's weights (float16), its sizes and how it was
                                   trained in the safetensors metadata ("mlct": JSON)
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from safetensors import safe_open

from mlct.errors import MlctError, first_line
from mlct.io import atomic_path

if TYPE_CHECKING:
    from mlct.nn.critic import LatentCritic

FILE = "critic.safetensors"
FORMAT, VERSION = "mlct-critic", 1
DEFAULT_CANDIDATES = 8  # best of 8: docs/model_card.md measures 1, 4 and 8
MAX_CANDIDATES = 64
# the first candidate within this much (cosine) of the best: docs/model_card.md measures 0-0.1
DEFAULT_MARGIN = 0.05


def save_critic(model_dir: str | os.PathLike, critic: LatentCritic, training: dict[str, Any],
                text_encoder: str, candidates: int = DEFAULT_CANDIDATES,
                margin: float = DEFAULT_MARGIN) -> Path:
    """Write MODEL_DIR/critic.safetensors atomically (float16 weights)."""
    import torch
    from safetensors.torch import save

    info = {"format": FORMAT, "version": VERSION, "text_encoder": text_encoder,
            "latent_size": critic.latent_size, "text_dim": critic.text_dim,
            "max_frames": critic.max_frames, "hidden": critic.hidden, "width": critic.width,
            "candidates": candidates, "margin": margin, "training": training}
    tensors = {k: v.detach().to(torch.float16).contiguous() for k, v in critic.state_dict().items()}
    path = Path(model_dir) / FILE
    with atomic_path(path) as tmp:  # bytes, so that the file gets atomic_path's permissions
        tmp.write_bytes(save(tensors, metadata={"mlct": json.dumps(info)}))
    return path


class Critic:
    """A loaded critic: the network (torch) or its score as an ONNX graph (the shipped
    critic.onnx: onnx_assets.py), its info, and the pick among N latents. `margin` may be
    set on a loaded model (0: always the best)."""

    def __init__(self, network: LatentCritic | None, info: dict[str, Any],
                 session: Any = None) -> None:
        self.network = None if network is None else network.eval().requires_grad_(False)
        self.session = session
        self.info = info
        self.candidates = int(info.get("candidates", DEFAULT_CANDIDATES))
        self.margin = check_margin(info.get("margin", DEFAULT_MARGIN))

    def best(self, z: Any, frames: Sequence[int] | Any, text_emb: Any, candidates: int) -> Any:
        """z (B * N, n, d) autoencoder latents, N = candidates consecutive rows per prompt;
        frames (B,), text_emb (B, c) -> (B,) the index of each prompt's pick within its N
        (pick). Numpy arrays through the graph, tensors through the network (where the critic
        has one), the index of the same kind."""
        rows = z.shape[0] // candidates
        if self.session is not None and (isinstance(z, np.ndarray) or self.network is None):
            array = np.asarray(z, dtype=np.float32) if isinstance(z, np.ndarray) else (
                z.detach().float().cpu().numpy())
            text = text_emb if isinstance(text_emb, np.ndarray) else (
                text_emb.detach().float().cpu().numpy())
            (scores,) = self.session.run(None, {
                "z": array, "frames": np.repeat(np.asarray(frames, np.float32), candidates),
                "text": np.repeat(np.asarray(text, np.float32), candidates, axis=0)})
            best = pick(scores.reshape(rows, candidates), self.margin)
            return best if isinstance(z, np.ndarray) else _tensor(best)
        import torch

        with torch.inference_mode():
            frames = torch.as_tensor(frames)
            scores = self.network.score(torch.as_tensor(z).float(),
                                        frames.repeat_interleave(candidates).float(),
                                        torch.as_tensor(text_emb).float()
                                        .repeat_interleave(candidates, dim=0))
            best = pick(scores.view(rows, candidates).float().cpu().numpy(), self.margin)
        return best if isinstance(z, np.ndarray) else _tensor(best)


def pick(scores: np.ndarray, margin: float) -> np.ndarray:
    """(B, N) scores, candidates in seed order -> (B,) the first within `margin` of its row's
    best (0: the best; ties go to the first)."""
    scores = np.asarray(scores, dtype=np.float32)
    return np.argmax(scores >= scores.max(axis=1, keepdims=True) - np.float32(margin), axis=1)


def _tensor(array: np.ndarray) -> Any:
    import torch

    return torch.from_numpy(array)


def read_critic(model_dir: str | os.PathLike, text_encoder: str, text_dim: int,
                latent_size: int, graph: str | os.PathLike | None = None,
                threads: int | None = None) -> Critic | None:
    """The model folder's critic, None when it has none; MlctError when it is damaged or does
    not fit the model (another text encoder, latent or text width). graph: its score as an
    ONNX graph (made from this critic.safetensors: the caller checks), run by ONNX Runtime on
    `threads` instead of the network, which is then not built (no torch)."""
    path = Path(model_dir) / FILE
    if not path.is_file():
        return None
    try:
        framework = "numpy" if graph is not None else "pt"
        with safe_open(str(path), framework=framework) as f:  # one read: metadata, tensors
            info = json.loads((f.metadata() or {})["mlct"])
            tensors = {} if graph is not None else {name: f.get_tensor(name) for name in f.keys()}
        if info.get("format") != FORMAT or info.get("version") != VERSION:
            raise ValueError(f"not {FORMAT} version {VERSION}")
        network = None
        if graph is None:
            from mlct.nn.critic import LatentCritic

            network = LatentCritic(int(info["latent_size"]), int(info["text_dim"]),
                                   int(info["max_frames"]), int(info["hidden"]),
                                   int(info["width"]))
            network.load_state_dict({k: v.float() for k, v in tensors.items()})
    except Exception as error:  # safetensors, json and load_state_dict raise several kinds
        raise MlctError(f"{path}: not a critic ({first_line(error)})") from None
    if info["text_encoder"] != text_encoder or info["text_dim"] != text_dim:
        raise MlctError(f"{path}: trained for the text encoder {info['text_encoder']!r}, the "
                        f"model uses {text_encoder!r}; retrain it with `mlct train critic`")
    if info["latent_size"] != latent_size:
        raise MlctError(f"{path}: made for a {info['latent_size']}-number latent, the model's "
                        f"has {latent_size}; retrain it with `mlct train critic`")
    if graph is not None:
        from mlct.onnx_io import session

        return Critic(None, info, session(graph, threads))
    return Critic(network, info)


def check_margin(value: object) -> float:
    """A critic margin (a cosine difference, 0..2), or MlctError naming what is wrong."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 2:
        raise MlctError(f"the critic's margin must be a number in 0..2, got {value!r}")
    return float(value)


def set_margin(generator: Any, margin: float) -> None:
    """A loaded model's critic margin set to `margin` (checked), for the calls that follow;
    MlctError when the model has no critic."""
    if generator.critic is None:
        raise MlctError("--critic-margin: this model has no critic to choose among candidates")
    generator.critic.margin = check_margin(margin)


def check_candidates(value: object) -> int:
    """A candidate count, or MlctError naming what is wrong."""
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_CANDIDATES:
        raise MlctError(f"candidates must be a whole number in 1..{MAX_CANDIDATES}, got {value!r}")
    return value
