"""Writing a bundle's ONNX graphs (`mlct convert MODEL_DIR --onnx`, `mlct export RUN --onnx`)
in the format bundle.py owns: the torch modules exported and each graph checked against them."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from mlct.config import config_from_dict
from mlct.errors import MlctError
from mlct.generate.backends.onnx.bundle import (DECODER, DECODER_IO, DENOISER, DENOISER_IO,
                                                MANIFEST, ONNX_DIR, ONNX_FORMAT, ONNX_VERSION,
                                                TEXT_ENCODER, weights_digest)
from mlct.generate.backends.pytorch import bundle_networks
from mlct.generate.bundle import BUNDLE_FILES, CONFIG, OPTIONAL_FILES, read_bundle
from mlct.io import atomic_dir, check_writable_dir
from mlct.nn.autoencoder import LatentAutoencoder
from mlct.nn.inference import for_inference
from mlct.onnx_io import OPSET, export_graph, onnxruntime_module, session
from mlct.text.minilm_onnx import check_onnx_spec, write_minilm_graph

PARITY = 1e-3  # the most a graph's output may differ from the torch module's when written


class DecoderGraph(nn.Module):
    """The AE decoder with the frame count read from the mask's shape, so that it stays free in
    the graph: (latent (B, n, d), valid (B, T) bool) -> normalized features (B, T, D)."""

    def __init__(self, ae: LatentAutoencoder) -> None:
        super().__init__()
        self.ae = ae

    def forward(self, latent: Tensor, valid: Tensor) -> Tensor:
        return self.ae.decode(latent, valid.sum(1), valid.shape[1])


def write_onnx_graphs(model_dir: str | os.PathLike, into: str | os.PathLike,
                      int8: bool = False, fused_text: bool = True) -> Path:
    """Write the ONNX graphs of the bundle in model_dir into the (empty) directory `into`,
    each checked against its torch module on a probe; returns `into`.

    int8: then the denoiser's matrix products run in int8 with a scale per 32 weights
    (ONNX Runtime's MatMulNBits, onnx_compact.quantize_blockwise_int8): sampling faster on one
    CPU thread, joints a few mm from float32's on average (docs/performance.md; tests/test_onnx.py
    bounds them). The decoder stays float32 (its convolutions ran 3x
    slower quantized), and so does the text encoder: quantized, it was 2x faster but moved the
    joints 27 mm on average, as a slightly different sentence would.
    fused_text: the text encoder with ONNX Runtime's fused transformer operators
    (minilm_onnx.write_minilm_graph); False keeps standard operators (the browser page)."""
    model_dir, into = Path(model_dir), Path(into)
    meta, tensors = read_bundle(model_dir)
    spec = check_onnx_spec(meta["text_encoder"])  # before any work
    onnxruntime_module()  # the graphs are checked with it: its absence is said first
    config = config_from_dict(meta["config"], "model config")
    ae, denoiser = bundle_networks(config, meta, tensors)
    # plain products (no oneDNN packing): the layers that sample in torch, as graph operators
    ae, denoiser = for_inference(ae, prepack=False), for_inference(denoiser, prepack=False)
    n, d = ae.latent_shape
    probe = torch.Generator().manual_seed(0)
    x = torch.randn(2, n, d, generator=probe)
    t = torch.tensor([0.9, 0.05])
    text = torch.randn(2, meta["text_dim"], generator=probe)
    batch = {0: "batch"}
    export_graph(denoiser, (x, t, text), into / DENOISER, *DENOISER_IO,
                 {name: batch for name in (*DENOISER_IO[0], *DENOISER_IO[1])})
    frames = min(ae.max_len, 40)
    valid = torch.arange(frames)[None, :] < torch.tensor([frames, frames // 2])[:, None]
    latent = torch.rand(2, n, d, generator=probe) * 2 - 1
    free = {0: "batch", 1: "frames"}
    export_graph(DecoderGraph(ae), (latent, valid), into / DECODER, *DECODER_IO,
                 {"latent": batch, "valid": free, "features": free})
    write_minilm_graph(spec, into / TEXT_ENCODER, fused=fused_text)
    with torch.no_grad():  # the graphs against the modules, on other sizes than traced
        x3, t3, text3 = (torch.cat([v, v[:1]]) for v in (x, t, text))
        _check(into / DENOISER, {"x_t": x3, "t": t3, "text": text3}, denoiser(x3, t3, text3))
        valid = torch.arange(ae.max_len)[None, :] < torch.tensor([ae.max_len, 7, 60])[:, None]
        latent3 = torch.cat([latent, latent[:1]])
        _check(into / DECODER, {"latent": latent3, "valid": valid},
               DecoderGraph(ae)(latent3, valid))
    manifest = {"format": ONNX_FORMAT, "version": ONNX_VERSION,
                "weights_sha256": weights_digest(model_dir), "text_encoder": spec,
                "opset": OPSET, "torch": torch.__version__,
                "graphs": {"text_encoder": TEXT_ENCODER, "denoiser": DENOISER,
                           "decoder": DECODER}}
    from mlct.generate.backends.onnx.sampler import STEPS_TABLE, write_steps_table
    from mlct.generate.samplers import ConsistencySampler, sampler_class

    sampler = sampler_class(meta["sampler"])(config)
    if isinstance(sampler, ConsistencySampler):  # every step count's coefficients: the
        write_steps_table(sampler, into / STEPS_TABLE)  # graphs then sample without torch
        manifest["steps_table"] = STEPS_TABLE
    if int8:
        from mlct.generate.backends.onnx.compact import INT8_BLOCK, quantize_blockwise_int8

        quantize_blockwise_int8(into / DENOISER, into / DENOISER)
        manifest["int8"] = ["denoiser"]
        manifest["int8_block"] = INT8_BLOCK
    (into / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    return into


def _check(graph: Path, inputs: dict[str, Tensor], expected: Tensor) -> None:
    """MlctError unless the graph gives what the module gave (within PARITY)."""
    (out,) = session(graph).run(None, {k: v.numpy() for k, v in inputs.items()})
    gap = float(np.abs(out - expected.numpy()).max()) if out.shape == expected.shape else np.inf
    if not gap <= PARITY:
        raise MlctError(f"{graph.name}: the ONNX graph differs from the torch network by {gap:.3g}"
                        f" (more than {PARITY:g}); this model cannot run on the onnx backend")


def convert_to_onnx(model_dir: str | os.PathLike, out: str | os.PathLike | None = None,
                    read_only: bool = False, int8: bool = False) -> Path:
    """`mlct convert MODEL_DIR --onnx [--out DIR]`: the bundle with its ONNX graphs.

    Without out, the graphs go into MODEL_DIR/onnx/ (replacing older ones); with out, the
    bundle is copied to out and the graphs written there. read_only: MODEL_DIR must not be
    written (the model inside the package). Returns the directory that now holds both."""
    model_dir = Path(model_dir)
    read_bundle(model_dir)  # a bundle, or one line saying what is wrong, before any work
    target = model_dir if out is None else Path(out)
    in_place = target.exists() and target.resolve() == model_dir.resolve()
    if in_place and (read_only or not os.access(model_dir, os.W_OK | os.X_OK)):
        why = ("lives inside the mlct package" if read_only else "is not writable")
        raise MlctError(f"{model_dir} {why}: give --out DIR, and the model is copied there "
                        f"with its ONNX graphs")
    if in_place:
        with atomic_dir(model_dir / ONNX_DIR) as tmp:
            write_onnx_graphs(model_dir, tmp, int8)
        return model_dir
    check_writable_dir(target)
    if target.exists() and (not target.is_dir() or (any(target.iterdir())
                                                    and not (target / CONFIG).is_file())):
        raise MlctError(f"{target} exists and is not a model directory; give a new or empty "
                        f"directory to --out")
    with atomic_dir(target) as tmp:
        for name in BUNDLE_FILES + OPTIONAL_FILES:  # durations and critic travel with it
            if (model_dir / name).is_file():
                shutil.copy2(model_dir / name, tmp / name)
        (tmp / ONNX_DIR).mkdir()
        write_onnx_graphs(tmp, tmp / ONNX_DIR, int8)
    return target
