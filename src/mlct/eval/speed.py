"""The models and sentences the speed benchmarks time (bench/inference_speed.py,
bench/paired_speed.py): the bundled model or a preset's networks with seeded random weights
(time does not depend on the values), and the same onnx conversion `mlct convert` makes."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

FRAMES, FEATURE_DIM, TEXT_DIM = 196, 263, 384
DEFAULT_FRAMES = 100  # generate()'s default 5 s at 20 fps
TEXTS = ["a person walks forward", "someone jumps up and down twice", "a man waves his right hand",
         "the person turns around and sits down", "a person kicks with the left leg",
         "someone runs in a circle", "a person bends down to pick something up",
         "a figure raises both arms above the head", "the person walks backwards slowly",
         "a person does a cartwheel", "someone stretches the arms to the sides",
         "a man walks forward then stops and waves", "a person crouches and stands up",
         "the person steps to the left", "a person claps the hands three times",
         "someone spins on the spot"]
SMALL_MODEL_ENV = "MLCT_BENCH_SMALL_MODEL"  # --small-model, for the child processes


def small_model_dir() -> Path:
    """The bundle timed as the small CM: $MLCT_BENCH_SMALL_MODEL's, else the bundled model."""
    from mlct.generate.bundle import bundled_model_dir

    return Path(os.environ.get(SMALL_MODEL_ENV) or bundled_model_dir())


def bundle_in_memory(preset: str, sampler: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The bundled model for the small CM; otherwise a preset's networks with seeded random
    weights, as mlct.generate.bundle.read_bundle returns a bundle: (meta, tensors)."""
    import torch

    from mlct.config import load_config
    from mlct.generate.bundle import ENCODER_PREFIXES, read_bundle
    from mlct.nn.build import build_autoencoder, build_denoiser
    if (preset, sampler) == ("small", "consistency"):
        return read_bundle(small_model_dir())
    config = load_config(preset)
    torch.manual_seed(0)
    ae, den = build_autoencoder(config, FEATURE_DIM), build_denoiser(config, TEXT_DIM)
    tensors = {f"decoder.{k}": v for k, v in ae.state_dict().items()
               if not k.startswith(ENCODER_PREFIXES)}
    tensors.update({f"denoiser.{k}": v for k, v in den.state_dict().items()})
    tensors.update({"norm.mean": torch.zeros(FEATURE_DIM), "norm.std": torch.ones(FEATURE_DIM)})
    meta = {"config": config.to_dict(), "sampler": sampler, "feature_dim": FEATURE_DIM,
            "skeleton": "humanml3d", "text_encoder": "minilm", "text_dim": TEXT_DIM}
    return meta, tensors


def onnx_generator(preset: str, sampler: str, folder: str, threads: int | None = None,
                   int8: bool = False) -> Any:
    """The model of bundle_in_memory written to folder as a bundle, converted (mlct convert
    --onnx, and --int8 when int8: the denoiser's products in int8) and loaded with the onnx
    backend; threads: ONNX Runtime's (None: torch's)."""
    from safetensors.torch import save_file

    from mlct.generate.bundle import BUNDLE_FORMAT, BUNDLE_VERSION
    from mlct.generate.load import load_onnx
    from mlct.generate.backends.onnx.convert import convert_to_onnx

    meta, tensors = bundle_in_memory(preset, sampler)
    save_file({k: v.contiguous() for k, v in tensors.items()},
              str(Path(folder) / "model.safetensors"))
    (Path(folder) / "config.json").write_text(json.dumps(
        {**meta, "format": BUNDLE_FORMAT, "version": BUNDLE_VERSION}), encoding="utf-8")
    return load_onnx(convert_to_onnx(folder, int8=int8), threads=threads)
