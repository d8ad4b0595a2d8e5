"""Frozen text encoders: caption -> one embedding vector, the condition c of the denoiser.

The paper conditions on the pooled, projected CLIP ViT-L/14 text embedding (768-d). The default
here is the bundled all-MiniLM-L6-v2 (384-d) so everything runs offline out of the box; any
sentence-transformers or CLIP directory on disk can be plugged in through `load_text_encoder`.

Everything loads from local paths only: nothing here downloads. The heavy libraries
(transformers, sentence-transformers) are imported inside the loaders so `import mlct` stays fast;
the bundled MiniLM does not need them at all (minilm.py runs it in plain torch, seconds sooner).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from mlct.errors import MlctError, first_line
from mlct.text.base import TextEncoder
from mlct.text.minilm_files import (MINILM, MINILM_SPECS, TOKEN_SLOTS, TOKENS_SUFFIX,  # noqa: F401
                                    bundled_minilm_path, token_slots_of)

CLIP_MAX_LENGTH = 77  # CLIP's context length; longer captions are truncated as in the paper
SPEC_FORMS = ("'minilm', 'minilm+tokens', 'minilm+sides', 'clip:/path/to/dir', 'st:/path/to/dir' or a model "
              "directory path")

# Files any of which means "the weights are here" (plain, sharded, or legacy PyTorch pickles).
_WEIGHT_PATTERNS = ("*.safetensors", "*.safetensors.index.json", "pytorch_model*.bin")


def _offline() -> None:
    """Keep Hugging Face libraries off the network (before they are first imported)."""
    # setdefault: a user who deliberately set these keeps their choice.
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    os.environ.setdefault("HF_HUB_DISABLE_TELEMETRY", "1")
    # The weight-loading progress bar would break our one-line output and the training bar.
    os.environ.setdefault("HF_HUB_DISABLE_PROGRESS_BARS", "1")
    try:
        from transformers.utils import logging as hf_logging

        hf_logging.disable_progress_bar()
        hf_logging.set_verbosity_error()
    except ImportError:  # the caller reports the missing library with its own message
        pass


def _resolve_device(device: str | torch.device | None) -> torch.device:
    return torch.device("cpu" if device is None else device)


class SentenceTransformerEncoder(TextEncoder):
    """Any sentence-transformers model directory, pooled as its own modules.json says."""

    def __init__(
        self,
        path: str | os.PathLike,
        name: str | None = None,
        device: str | torch.device | None = None,
        batch_size: int = 256,
        token_slots: int = 0,
    ) -> None:
        path = Path(path).expanduser().resolve()
        _check_model_dir(path, "st")
        self.token_slots = token_slots
        _offline()
        from sentence_transformers import SentenceTransformer

        try:
            # dtype fp32: recent transformers load in the checkpoint's dtype by default, and
            # half precision on the CPU is slow or unsupported.
            model = SentenceTransformer(
                str(path),
                device=str(_resolve_device(device)),
                local_files_only=True,
                model_kwargs={"dtype": torch.float32},
            )
        except (OSError, ValueError, KeyError, RuntimeError) as e:
            raise MlctError(
                f"cannot load a sentence-transformers model from {path}: {first_line(e)}"
            )
        self.model = model.eval().requires_grad_(False)
        self.name = name or f"st:{path}"
        self.path = path
        self.batch_size = batch_size
        # Probe rather than ask the model: the size it reports can be None (custom modules) or
        # disagree with what encode returns (truncate_dim). The probe is the null embedding.
        null = self._encode([""])
        self.dim = int(null.shape[-1])
        self._null = null[0]

    def _encode(self, texts: list[str]) -> Tensor:
        if self.token_slots:
            return self._encode_with_tokens(texts)
        # No normalize_embeddings: the model's own Normalize module (if any) already ran. numpy
        # output also turns encode's inference-mode tensors into ordinary ones, which autograd
        # accepts when the embedding later feeds a trained layer.
        arr = self.model.encode(
            texts,
            batch_size=self.batch_size,
            convert_to_numpy=True,
            show_progress_bar=False,
            normalize_embeddings=False,
        )
        return torch.from_numpy(arr).float().reshape(len(texts), -1)

    def _encode_with_tokens(self, texts: list[str]) -> Tensor:
        """(B, (1 + K) D): the pooled vector, then the first K token states, zero-padded."""
        outputs = self.model.encode(texts, batch_size=self.batch_size, output_value=None,
                                    show_progress_bar=False)
        rows = []
        for out in outputs:
            pooled = out["sentence_embedding"].detach().float().cpu()  # (D,)
            valid = out["attention_mask"].bool().cpu()  # the batch pads every caption
            states = out["token_embeddings"].detach().float().cpu()[valid][: self.token_slots]
            slots = states.new_zeros(self.token_slots, pooled.shape[0])
            slots[: states.shape[0]] = states
            rows.append(torch.cat([pooled, slots.flatten()]))
        return torch.stack(rows).clone()  # out of inference mode: later layers train on it


class ClipTextEncoder(TextEncoder):
    """CLIP text tower from a local directory: the projected pooled `text_embeds` (the paper's c).

    Works with a full CLIP checkpoint (e.g. openai/clip-vit-large-patch14, 768-d) or a saved
    `CLIPTextModelWithProjection`.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        device: str | torch.device | None = None,
        batch_size: int = 256,
    ) -> None:
        path = Path(path).expanduser().resolve()
        _check_model_dir(path, "clip")
        _offline()
        from transformers import CLIPTextModelWithProjection, CLIPTokenizer

        self.device = _resolve_device(device)
        try:
            self.tokenizer = CLIPTokenizer.from_pretrained(str(path), local_files_only=True)
            model = CLIPTextModelWithProjection.from_pretrained(
                str(path), local_files_only=True, dtype=torch.float32
            )
        except (OSError, ValueError, KeyError, RuntimeError) as e:
            raise MlctError(f"cannot load a CLIP text model from {path}: {first_line(e)}")
        self.model = model.to(self.device).eval().requires_grad_(False)
        self.name = f"clip:{path}"
        self.path = path
        self.batch_size = batch_size
        self.dim = int(model.config.projection_dim)
        # 77 for real CLIP; a smaller model cannot take more positions than it has.
        self.max_length = min(CLIP_MAX_LENGTH, int(model.config.max_position_embeddings))

    @torch.no_grad()  # not inference_mode: its tensors would be refused later by autograd
    def _encode(self, texts: list[str]) -> Tensor:
        chunks = []
        for i in range(0, len(texts), self.batch_size):
            # Padding to the longest caption instead of to 77 gives the same embedding: CLIP's
            # causal mask keeps the pooled (first end-of-text) token blind to the padding.
            tok = self.tokenizer(
                texts[i : i + self.batch_size],
                padding=True,
                truncation=True,
                max_length=self.max_length,
                return_tensors="pt",
            ).to(self.device)
            out = self.model(input_ids=tok["input_ids"], attention_mask=tok["attention_mask"])
            chunks.append(out.text_embeds.float().cpu())  # (b, projection_dim)
        return torch.cat(chunks)


def load_text_encoder(spec: str = MINILM, device: str | torch.device | None = None) -> TextEncoder:
    """Build a text encoder from a spec: 'minilm', 'clip:DIR', 'st:DIR' or a bare DIR."""
    if not isinstance(spec, str) or not spec.strip():
        raise MlctError(f"empty text encoder spec; use {SPEC_FORMS}")
    spec = spec.strip()
    if spec.lower() in MINILM_SPECS:
        # The lean loader (minilm.py): the same embeddings without importing sentence-transformers.
        from mlct.text.minilm import MiniLMEncoder

        return MiniLMEncoder(bundled_minilm_path(), name=spec.lower(), device=device,
                             token_slots=token_slots_of(spec))
    kind, sep, rest = spec.partition(":")
    if sep and kind.lower() in ("clip", "st"):
        if not rest:
            raise MlctError(f"text encoder spec {spec!r} names no directory; use {SPEC_FORMS}")
        kind, path = kind.lower(), Path(rest).expanduser()
    elif _looks_like_path(spec):
        path = Path(spec).expanduser()
        _check_dir_exists(path)
        kind = _detect_kind(path)
    else:
        raise MlctError(f"unknown text encoder {spec!r}; use {SPEC_FORMS}")
    if kind == "clip":
        return ClipTextEncoder(path, device=device)
    return SentenceTransformerEncoder(path, device=device)


def _looks_like_path(spec: str) -> bool:
    if Path(spec).expanduser().exists():
        return True
    # "bert" or "t5:/dir" is a mistyped spec, not a directory that happens to be missing. One
    # letter before the colon is a Windows drive, not a kind.
    if re.match(r"[A-Za-z][\w.+-]+:", spec):
        return False
    return os.sep in spec or "/" in spec or spec.startswith((".", "~"))


def _check_dir_exists(path: Path) -> None:
    if not path.exists():
        raise MlctError(
            f"text encoder directory {path} does not exist; point at a local CLIP or "
            "sentence-transformers model directory, or use 'minilm'"
        )
    if not path.is_dir():
        raise MlctError(f"text encoder path {path} is a file; point at the model's directory")


def _read_config(path: Path) -> dict[str, Any]:
    try:
        return json.loads((path / "config.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _is_clip_config(config: dict[str, Any]) -> bool:
    model_type = str(config.get("model_type", "")).lower()
    archs = " ".join(map(str, config.get("architectures") or [])).lower()
    return model_type.startswith("clip") or "clip" in archs


def _detect_kind(path: Path) -> str:
    """'st' for a directory with modules.json, 'clip' for a CLIP config.json."""
    if (path / "modules.json").is_file():
        return "st"
    if _is_clip_config(_read_config(path)):
        return "clip"
    raise MlctError(
        f"cannot tell which model {path} holds: expected modules.json (sentence-transformers) "
        "or a CLIP config.json; say which with 'st:DIR' or 'clip:DIR'"
    )


def _has_weights(path: Path) -> bool:
    # Sentence-transformers keep the transformer in a subfolder in older layouts (0_Transformer/).
    for pattern in _WEIGHT_PATTERNS:
        if any(path.glob(pattern)) or any(path.glob(f"*/{pattern}")):
            return True
    return False


def _check_model_dir(path: Path, kind: str) -> None:
    """Fail in one line, before the libraries do in fifty, on a directory that cannot load."""
    _check_dir_exists(path)
    if kind == "st" and not (path / "modules.json").is_file():
        raise MlctError(
            f"{path} has no modules.json, so it is not a sentence-transformers model; "
            "use 'clip:DIR' for CLIP or point at a sentence-transformers directory"
        )
    if kind == "clip":
        config = _read_config(path)
        if not config:
            raise MlctError(f"{path} has no readable config.json; point at a CLIP model directory")
        if not _is_clip_config(config):
            found = config.get("model_type", "unknown")
            raise MlctError(f"{path} holds a {found!r} model, not CLIP; use 'st:DIR' or a CLIP dir")
    if not _has_weights(path):
        raise MlctError(
            f"{path} has no model weights (*.safetensors or pytorch_model.bin); "
            "point at a directory that holds a downloaded model"
        )
