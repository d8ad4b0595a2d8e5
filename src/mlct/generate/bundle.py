"""Inference bundles: `mlct export RUN --out MODEL_DIR` writes one (train/export.py),
`mlct.load` reads it (this module owns the format).

A bundle is a directory:
- model.safetensors: the AE decoder ("decoder.*"), the sampling denoiser ("denoiser.*": the EMA
  weights), the normalization ("norm.mean", "norm.std"), and the AE encoder ("ae_encoder.*"),
  which generation never reads: it is there so that `mlct train ae|cm --init MODEL_DIR`
  fine-tunes the model on a user's own data;
- config.json: the full run config, the sampler's name (mlct.generate.samplers), feature
  width, skeleton, text encoder;
- Mean.npy, Std.npy: the dataset statistics, in the standard layout's names;
- optionally onnx/: the networks as ONNX graphs for the onnx backend (backends/onnx/bundle.py owns them);
- optionally durations.json (durations.py), critic.safetensors (critic.py) and
  text_anchors.safetensors (compose/text_anchors.py).
It holds no optimizer state and no text-encoder weights (the text encoder is named and loaded
from its own package or directory).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mlct.errors import MlctError, MlctWarning, first_line
from mlct.generate.samplers import SAMPLERS
from mlct.io import read_format_json, strip_prefix

if TYPE_CHECKING:
    import torch

BUNDLE_FORMAT = "mlct-model"
BUNDLE_VERSION = 1
ENCODER_PREFIXES = ("enc_in.", "enc_tokens", "enc_pos", "encoder.", "to_tokens.", "arm_encoder.",
                    "arm_to_tokens.")
ENCODER_KEY = "ae_encoder"  # the AE encoder's tensors in a bundle (since stage-1 fine-tuning)
META_KEYS = ("sampler", "config", "feature_dim", "skeleton", "text_encoder", "text_dim")
CONFIG, WEIGHTS = "config.json", "model.safetensors"
BUNDLE_FILES = (CONFIG, WEIGHTS, "Mean.npy", "Std.npy")  # a bundle's files (its onnx/ aside)
# what a model may carry besides (generate/compose/durations.py, critic.py, compose/text_anchors.py)
OPTIONAL_FILES = ("durations.json", "critic.safetensors", "text_anchors.safetensors")



def bundle_autoencoder_state(tensors: dict[str, torch.Tensor], path: str | os.PathLike
                             ) -> dict[str, torch.Tensor]:
    """The whole AE state dict (encoder and decoder) of a bundle read by `read_bundle`."""
    encoder = strip_prefix(tensors, ENCODER_KEY)
    if not encoder:
        raise MlctError(f"{path}: this model ships no autoencoder encoder (exported by an "
                        f"older mlct); it can start `mlct train cm --init` but not `train ae`")
    return {**strip_prefix(tensors, "decoder"), **encoder}


def _check_meta(meta: dict[str, Any], config_path: Path) -> None:
    """The values the loader builds from, checked: a damaged config.json is one line naming
    the key, not a ValueError from the skeleton table or a TypeError from a layer's width."""
    from mlct.motion.skeleton import SKELETONS

    def bad(key: str, expected: str) -> MlctError:
        return MlctError(f"{config_path}: '{key}' is {meta[key]!r}, expected {expected}")

    if meta["sampler"] not in SAMPLERS:
        raise bad("sampler", " or ".join(repr(s) for s in SAMPLERS))
    if meta["skeleton"] not in SKELETONS:
        raise bad("skeleton", " or ".join(repr(s) for s in SKELETONS))
    for key in ("feature_dim", "text_dim"):
        value = meta[key]
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise bad(key, "a positive integer")
    if meta["feature_dim"] != SKELETONS[meta["skeleton"]].feature_dim:
        raise bad("feature_dim", f"{SKELETONS[meta['skeleton']].feature_dim} for the "
                  f"{meta['skeleton']} skeleton")
    if not isinstance(meta["text_encoder"], str):
        raise bad("text_encoder", "the text encoder's name (a string)")
    if not isinstance(meta["config"], dict):
        raise bad("config", "the run's config (a mapping)")


_NOTED: set[str] = set()  # models whose training data's license has been said this process


def training_data_notice(meta: dict[str, Any], path: str | os.PathLike) -> None:
    """One MlctWarning, once a process per model, when its config's `training_data` names a
    corpus whose license forbids commercial use (a model trained on Bandai Namco's, say):
    whoever loads it is told, wherever it is loaded."""
    corpora = (meta.get("training_data") or {}).get("corpora", [])
    restricted = [c for c in corpora if c.get("commercial_use") is False]
    if not restricted or str(path) in _NOTED:
        return
    _NOTED.add(str(path))
    named = "; ".join(f"{c.get('source', c.get('corpus'))} ({c.get('license')})"
                      for c in restricted)
    warnings.warn(f"{path}: this model was trained on {named}: non-commercial use only",
                  MlctWarning, stacklevel=3)


def read_config(path: str | os.PathLike) -> dict[str, Any]:
    """A bundle's config.json alone, checked: a one-line MlctError naming a missing field."""
    config_path = Path(path) / CONFIG
    meta = read_format_json(config_path, BUNDLE_FORMAT, BUNDLE_VERSION, "an mlct model config")
    missing = [k for k in META_KEYS if k not in meta]
    if missing:
        raise MlctError(f"{config_path}: incomplete model config (no {', '.join(missing)})")
    _check_meta(meta, config_path)
    return meta


def read_bundle(path: str | os.PathLike, numpy: bool = False
                ) -> tuple[dict[str, Any], dict[str, Any]]:
    """config.json and the tensors of a bundle, float16 ones as float32; one-line MlctError
    when it is not one. numpy: numpy arrays (the onnx backend, without torch), each read when
    first asked for (_LazyArrays), else tensors."""
    path = Path(path)
    if not path.is_dir():
        raise MlctError(f"{path}: no such model directory")
    config_path, weights = path / CONFIG, path / WEIGHTS
    if not config_path.is_file() or not weights.is_file():
        raise MlctError(f"{path}: not an mlct model (needs config.json and model.safetensors; "
                        f"make one with `mlct export RUN --out {path}`)")
    meta = read_config(path)
    training_data_notice(meta, path)
    # where the bundle was read from: the generator reads its critic.safetensors (critic.py)
    # from there; set on every read, so a config.json copied elsewhere never points back
    meta["model_dir"] = str(path)
    try:
        if numpy:
            return meta, _LazyArrays(weights)
        from safetensors.torch import load_file

        tensors = load_file(str(weights))
    except Exception as err:  # safetensors raises several kinds on a damaged file
        raise MlctError(f"{weights}: unreadable weights ({first_line(err)})") from None
    import torch

    return meta, {k: (v.float() if v.dtype == torch.float16 else v) for k, v in tensors.items()}


class _LazyArrays(Mapping[str, Any]):
    """A bundle's tensors as numpy arrays, float16 ones as float32, each read from its
    model.safetensors when first asked for (the file's header is checked at once): the onnx
    backend reads the normalization at load and the rest only when a large batch builds the
    torch networks (reading and converting all of them took ~20 ms of a cold start)."""

    def __init__(self, weights: Path) -> None:
        from safetensors import safe_open

        self._file = safe_open(str(weights), framework="numpy")
        self._keys = tuple(self._file.keys())
        self._read: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        if key not in self._read:
            if key not in self._keys:
                raise KeyError(key)
            import numpy as np

            value = self._file.get_tensor(key)
            self._read[key] = value.astype(np.float32) if value.dtype == np.float16 else value
        return self._read[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)


def bundled_model_dir() -> Path:
    """The model shipped inside the package (docs/model_card.md): small preset, MiniLM text."""
    return Path(__file__).resolve().parent.parent / "assets" / "model"
