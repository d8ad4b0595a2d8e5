"""A bundle's ONNX graphs: `mlct convert MODEL_DIR --onnx` and `mlct export RUN --onnx` write
them (convert.py), the onnx backend (networks.py) reads them; this module owns their format.

MODEL_DIR/onnx/ holds
- text_encoder.onnx: the MiniLM network, (ids, mask) -> (embedding, states)
  (text/minilm_onnx.py; the tokenizer stays the `tokenizers` library);
- denoiser.onnx: the network F of Eq. 11, (x_t (B, n, d), t (B,), text (B, c)) -> F (B, n, d).
  F, not the consistency function S: the sampler objects (generate/samplers) apply the
  parameterization (Eq. 11, or DDIM's noise prediction), the clamp and the re-noising around it,
  as they do around the torch network. One sampler code for both backends, and its noise drawn
  from the same torch.Generator, so a seed gives the same motion on either;
- decoder.onnx: the AE decoder, (latent (B, n, d), valid (B, T) bool) -> normalized features
  (B, T, D), T free (the longest length asked for); the pipeline divides by latent_scale before
  it and denormalizes after it, as for the torch decoder;
- onnx.json: format and version, the sha256 of the model.safetensors the graphs were made from
  (graphs of another model are refused, not run), the text encoder, the opset.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mlct.errors import MlctError
from mlct.generate.bundle import WEIGHTS, bundled_model_dir
from mlct.io import read_format_json
from mlct.shipped import SHIPPED_DIR, is_shipped_model

ONNX_DIR = "onnx"  # in the model directory
MANIFEST = "onnx.json"
ONNX_FORMAT, ONNX_VERSION = "mlct-onnx", 1
TEXT_ENCODER, DENOISER, DECODER = "text_encoder.onnx", "denoiser.onnx", "decoder.onnx"
DENOISER_IO = (("x_t", "t", "text"), ("f",))
DECODER_IO = (("latent", "valid"), ("features",))


@dataclass(frozen=True)
class OnnxGraphs:
    """The graph files of a model directory, checked against its weights (read_onnx)."""

    text_encoder: Path
    denoiser: Path
    decoder: Path
    manifest: dict[str, Any]
    # the package's own graphs of the bundled model, whose digests the tests check
    # (tests/test_onnx_assets.py) instead of every load (~10-20 ms of a cold start)
    shipped: bool = False


def weights_digest(model_dir: Path) -> str:
    """The sha256 of the bundle's model.safetensors (hex); remembered per file, size and
    modification time, as loading asks for it up to three times (backends/auto.py)."""
    path = (Path(model_dir) / WEIGHTS).resolve()
    stat = path.stat()
    key = (str(path), stat.st_size, stat.st_mtime_ns)
    if key not in _DIGESTS:
        digest = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        _DIGESTS[key] = digest.hexdigest()
    return _DIGESTS[key]


_DIGESTS: dict[tuple[str, int, int], str] = {}


def read_onnx(model_dir: str | os.PathLike, text_encoder: str,
              folder: str | os.PathLike | None = None) -> OnnxGraphs:
    """The ONNX graphs of a bundle, checked: present, of this format, made from its weights and
    for its text encoder; a one-line MlctError naming the problem and the fix otherwise.
    folder: where the graphs are (default MODEL_DIR/onnx; the cache's, backends/auto.py)."""
    model_dir = Path(model_dir)
    folder = model_dir / ONNX_DIR if folder is None else Path(folder)
    make = f"make them with `mlct convert {model_dir} --onnx`"
    if model_dir.resolve() == bundled_model_dir():  # inside the package: not written there
        make = ("make a copy that has them with `mlct convert bundled --onnx --out DIR`, "
                "then load DIR")
    if not (folder / MANIFEST).is_file():
        raise MlctError(f"{model_dir}: no ONNX graphs ({ONNX_DIR}/{MANIFEST}); {make}")
    manifest = read_format_json(folder / MANIFEST, ONNX_FORMAT, ONNX_VERSION,
                                "the description of a model's ONNX graphs")
    graphs = {k: folder / v for k, v in (manifest.get("graphs") or {}).items()
              if isinstance(v, str)}
    missing = [name for name in ("text_encoder", "denoiser", "decoder")
               if name not in graphs or not graphs[name].is_file()]
    if missing:
        raise MlctError(f"{folder}: the {', '.join(missing)} graph is missing; {make}")
    shipped = is_shipped_model(model_dir) and folder.resolve() == SHIPPED_DIR
    if not shipped and manifest.get("weights_sha256") != weights_digest(model_dir):
        raise MlctError(f"{folder}: the ONNX graphs were made from another {WEIGHTS}; {make}")
    if manifest.get("text_encoder") != text_encoder.strip().lower():
        raise MlctError(f"{folder}: the ONNX graphs were made for the text encoder "
                        f"{manifest.get('text_encoder')!r}, the model uses {text_encoder!r}; "
                        f"{make}")
    return OnnxGraphs(graphs["text_encoder"], graphs["denoiser"], graphs["decoder"], manifest,
                      shipped)
