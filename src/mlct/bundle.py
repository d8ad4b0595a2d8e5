"""Inference bundles: `mlct export RUN --out MODEL_DIR` writes one, `mlct.load` reads it.

A bundle is a directory:
- model.safetensors: the AE decoder ("decoder.*"), the sampling denoiser ("denoiser.*": the EMA
  weights), the normalization ("norm.mean", "norm.std"), and the AE encoder ("ae_encoder.*"),
  which generation never reads: it is there so that `mlct train ae|cm --init MODEL_DIR`
  fine-tunes the model on a user's own data;
- config.json: the full run config, the sampler kind, feature width, skeleton, text encoder;
- Mean.npy, Std.npy: the dataset statistics, in the standard layout's names.
It holds no optimizer state and no text-encoder weights (the text encoder is named and loaded
from its own package or directory).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from mlct.errors import MlctError
from mlct.io import atomic_dir, read_format_json
from mlct.train.checkpoint import strip_prefix

BUNDLE_FORMAT = "mlct-model"
BUNDLE_VERSION = 1
SAMPLERS = {"cm": "consistency", "diffusion": "ddim"}
ENCODER_PREFIXES = ("enc_in.", "enc_tokens", "enc_pos", "encoder.", "to_tokens.")
ENCODER_KEY = "ae_encoder"  # the AE encoder's tensors in a bundle (since stage-1 fine-tuning)
META_KEYS = ("sampler", "config", "feature_dim", "skeleton", "text_encoder", "text_dim")


def export_run(run: str | os.PathLike, out: str | os.PathLike, stage: str | None = None,
               half: bool = False) -> Path:
    """Write the inference bundle of RUN's latest `cm` (default) or `diffusion` checkpoint."""
    from mlct.train.checkpoint import latest_checkpoint, load_checkpoint  # only for export

    run, out = Path(run), Path(out)
    if stage is None:
        stage = "cm" if (run / "cm").is_dir() or not (run / "diffusion").is_dir() else "diffusion"
    if stage not in SAMPLERS:
        raise MlctError(f"cannot export stage '{stage}'; choose cm or diffusion")
    found = latest_checkpoint(run / stage / "checkpoints")
    if found is None:
        raise MlctError(f"{run / stage}: no checkpoint to export (train it first)")
    ckpt = load_checkpoint(found, with_state=False)
    ae = strip_prefix(ckpt.tensors, "ae")
    decoder = {k: v for k, v in ae.items() if not k.startswith(ENCODER_PREFIXES)}
    target = strip_prefix(ckpt.tensors, "target")
    if stage == "cm":
        # the EMA target network when trained with one, else the online weights
        denoiser = (strip_prefix(target, "module.net") if target
                    else strip_prefix(ckpt.tensors, "denoiser"))
    else:
        denoiser = strip_prefix(target, "module")
    encoder = {k: v for k, v in ae.items() if k.startswith(ENCODER_PREFIXES)}
    tensors = {**{f"decoder.{k}": v for k, v in decoder.items()},
               # shipped for `mlct train ae --init MODEL_DIR` (fine-tuning); generation skips it
               **{f"{ENCODER_KEY}.{k}": v for k, v in encoder.items()},
               **{f"denoiser.{k}": v for k, v in denoiser.items()},
               "norm.mean": ckpt.tensors["norm.mean"], "norm.std": ckpt.tensors["norm.std"]}
    if half:  # float16 storage halves the file; loading casts back to float32
        tensors = {k: (v.half() if v.is_floating_point() and not k.startswith("norm.") else v)
                   for k, v in tensors.items()}
    meta = {"format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "sampler": SAMPLERS[stage],
            "step": ckpt.meta["step"], "config": ckpt.meta["config"],
            "feature_dim": ckpt.meta["feature_dim"], "skeleton": ckpt.meta["skeleton"],
            "text_encoder": ckpt.meta["text_encoder"], "text_dim": ckpt.meta["text_dim"]}
    with atomic_dir(out) as tmp:
        save_file({k: v.contiguous() for k, v in tensors.items()}, str(tmp / "model.safetensors"),
                  metadata={"format": BUNDLE_FORMAT})
        (tmp / "config.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
        np.save(tmp / "Mean.npy", ckpt.tensors["norm.mean"].numpy())
        np.save(tmp / "Std.npy", ckpt.tensors["norm.std"].numpy())
    return out


def bundle_autoencoder_state(tensors: dict[str, torch.Tensor], path: str | os.PathLike
                             ) -> dict[str, torch.Tensor]:
    """The whole AE state dict (encoder and decoder) of a bundle read by `read_bundle`."""
    encoder = strip_prefix(tensors, ENCODER_KEY)
    if not encoder:
        raise MlctError(f"{path}: this model ships no autoencoder encoder (exported by an "
                        f"older mlct); it can start `mlct train cm --init` but not `train ae`")
    return {**strip_prefix(tensors, "decoder"), **encoder}


def read_bundle(path: str | os.PathLike) -> tuple[dict[str, Any], dict[str, torch.Tensor]]:
    """config.json and the tensors of a bundle; one-line MlctError when it is not one."""
    path = Path(path)
    if not path.is_dir():
        raise MlctError(f"{path}: no such model directory")
    config_path, weights = path / "config.json", path / "model.safetensors"
    if not config_path.is_file() or not weights.is_file():
        raise MlctError(f"{path}: not an mlct model (needs config.json and model.safetensors; "
                        f"make one with `mlct export RUN --out {path}`)")
    meta = read_format_json(config_path, BUNDLE_FORMAT, BUNDLE_VERSION, "an mlct model config")
    missing = [k for k in META_KEYS if k not in meta]
    if missing:
        raise MlctError(f"{config_path}: incomplete model config (no {', '.join(missing)})")
    try:
        tensors = load_file(str(weights))
    except Exception as err:  # safetensors raises several kinds on a damaged file
        raise MlctError(f"{weights}: unreadable weights ({str(err).splitlines()[0]})") from None
    return meta, {k: (v.float() if v.dtype == torch.float16 else v) for k, v in tensors.items()}
