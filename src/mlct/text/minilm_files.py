"""The bundled MiniLM's names and files, read without torch: its specs ("minilm",
"minilm+tokens", "minilm+sides"), where it lives (assets/minilm), BERT's sizes (config.json), the
sentence-transformers pipeline it must be (modules.json), and its tokenizer (tokenizer.json,
the `tokenizers` library). The torch encoder (minilm.py) and the ONNX one (minilm_onnx.py) both
start here.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mlct.errors import MlctError, first_line
from mlct.text.sides import SIDES_SUFFIX

MINILM = "minilm"  # the spec (and cache name) of the bundled all-MiniLM-L6-v2
# Suffix of a spec whose embedding also carries the token states: "minilm+tokens" gives
# [pooled (384), TOKEN_SLOTS x token state (384), zero rows past the caption's end].
TOKENS_SUFFIX = "+tokens"
TOKEN_SLOTS = 20  # wordpieces kept, [CLS] included; a two-action caption takes ~15
# The bundled MiniLM's specs: pooled, pooled + token states, pooled with the sides contrasted
# (text/sides.py).
MINILM_SPECS = (MINILM, MINILM + TOKENS_SUFFIX, MINILM + SIDES_SUFFIX)


def token_slots_of(spec: str) -> int:
    """The number of token-state slots in the embeddings of text encoder `spec` (0: pooled)."""
    return TOKEN_SLOTS if spec.strip().lower().endswith(TOKENS_SUFFIX) else 0


def bundled_minilm_path() -> Path:
    """Directory of the all-MiniLM-L6-v2 shipped in the package (assets/minilm, Apache-2.0):
    the torch encoder (minilm.py) and the shipped ONNX graph (onnx_assets.py) read its files."""
    from mlct.shipped import MINILM_DIR, MINILM_WEIGHTS

    if not (MINILM_DIR / MINILM_WEIGHTS).is_file():
        raise MlctError(f"the bundled MiniLM is missing from {MINILM_DIR}; reinstall mlct")
    return MINILM_DIR


# The sentence-transformers pipeline this loader reproduces, module by module (modules.json).
_PIPELINE = ("Transformer", "Pooling", "Normalize")
_MEAN_POOLING = {"pooling_mode_mean_tokens": True, "pooling_mode_cls_token": False,
                 "pooling_mode_max_tokens": False, "pooling_mode_mean_sqrt_len_tokens": False}
_DEFAULT_MAX_SEQ_LENGTH = 256  # sentence-transformers' default when the model names none


@dataclass(frozen=True)
class BertConfig:
    """The sizes of a BERT encoder, as its Hugging Face config.json gives them."""

    vocab_size: int
    hidden_size: int
    num_hidden_layers: int
    num_attention_heads: int
    intermediate_size: int
    max_position_embeddings: int
    type_vocab_size: int
    layer_norm_eps: float

    @classmethod
    def from_dict(cls, config: dict[str, Any]) -> BertConfig:
        """The sizes of a config.json dict; ValueError for a model this module cannot run."""
        unsupported = {
            "model_type": (config.get("model_type"), "bert"),
            "hidden_act": (config.get("hidden_act", "gelu"), "gelu"),
            "position_embedding_type": (config.get("position_embedding_type", "absolute"),
                                        "absolute"),
        }
        for key, (found, wanted) in unsupported.items():
            if found != wanted:
                raise ValueError(f"{key} is {found!r}; only {wanted!r} is supported")
        try:
            sizes = {name: int(config[name]) for name in (
                "vocab_size", "hidden_size", "num_hidden_layers", "num_attention_heads",
                "intermediate_size", "max_position_embeddings", "type_vocab_size")}
            eps = float(config.get("layer_norm_eps", 1e-12))
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"config.json lacks a usable {e}") from None
        if sizes["hidden_size"] % sizes["num_attention_heads"]:
            raise ValueError("hidden_size is not a multiple of num_attention_heads")
        return cls(**sizes, layer_norm_eps=eps)

    @classmethod
    def from_file(cls, path: str | Path) -> BertConfig:
        return cls.from_dict(json.loads(Path(path).read_text(encoding="utf-8")))


def check_pipeline(path: Path) -> int:
    """The max_seq_length of a sentence-transformers directory this module can run exactly;
    ValueError naming what differs (another pooling, a Dense layer, no Normalize...)."""
    modules = _read_json(path / "modules.json")
    kinds = tuple(str(m.get("type", "")).rsplit(".", 1)[-1] for m in modules)
    if kinds != _PIPELINE:
        raise ValueError(f"modules {kinds} are not {_PIPELINE}")
    pooling = _read_json(path / modules[1].get("path", "") / "config.json")
    for key, wanted in _MEAN_POOLING.items():
        if bool(pooling.get(key, False)) != wanted:
            raise ValueError(f"pooling {key} is {pooling.get(key)}, expected {wanted}")
    st_config = path / "sentence_bert_config.json"
    settings = _read_json(st_config) if st_config.is_file() else {}
    if settings.get("do_lower_case"):  # an extra lower-casing step; this tokenizer is uncased
        raise ValueError("do_lower_case is set")
    return int(settings.get("max_seq_length") or _DEFAULT_MAX_SEQ_LENGTH)


def _read_json(path: Path) -> Any:
    return json.loads(path.read_text(encoding="utf-8"))


def load_tokenizer(path: Path) -> tuple[Any, int, BertConfig]:
    """(tokenizer, max_length, sizes) of the MiniLM directory `path`: the tokenizer unpadded
    and truncated at max_length, the tokens per caption ([CLS] and [SEP] included); MlctError
    in one line when it cannot be read."""
    try:
        from tokenizers import Tokenizer
    except ImportError as e:
        raise MlctError(f"the MiniLM text encoder needs {e.name}: pip install {e.name}")
    try:
        config = BertConfig.from_file(path / "config.json")
        max_length = min(check_pipeline(path), config.max_position_embeddings)
        tokenizer = Tokenizer.from_file(str(path / "tokenizer.json"))
    except Exception as e:  # noqa: BLE001 - tokenizers raises its own kinds
        raise MlctError(f"cannot load the MiniLM text encoder from {path}: {first_line(e)}")
    # tokenizer.json pads and truncates to 128; sentence-transformers pads a batch to its
    # longest caption and truncates at the model's max_seq_length instead.
    tokenizer.no_padding()
    tokenizer.enable_truncation(max_length)
    return tokenizer, max_length, config
