"""`mlct export RUN --out MODEL_DIR`: a trained run's latest checkpoint as an inference bundle
(the format mlct.generate.bundle defines and reads)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from mlct.errors import MlctError
from mlct.generate.bundle import BUNDLE_FORMAT, BUNDLE_VERSION, ENCODER_KEY, ENCODER_PREFIXES
from mlct.generate.backends.onnx.bundle import ONNX_DIR
from mlct.generate.backends.onnx.convert import write_onnx_graphs
from mlct.generate.samplers import sampler_for_stage
from mlct.io import atomic_dir, readable_by_umask, strip_prefix
from mlct.train.checkpoint import latest_checkpoint, load_checkpoint

META_KEYS = ("step", "config", "feature_dim", "skeleton", "text_encoder", "text_dim")


def export_run(run: str | os.PathLike, out: str | os.PathLike, stage: str | None = None,
               half: bool = False, onnx: bool = False,
               decoder_from: str | os.PathLike | None = None) -> Path:
    """Write the inference bundle of RUN's latest `cm` (default) or `diffusion` checkpoint;
    onnx: with its networks as ONNX graphs too (generate/backends/onnx/bundle.py); decoder_from: an
    autoencoder run (or checkpoint) whose decoder replaces the run's, trained with the same
    encoder frozen (`ae.freeze_encoder`): refused when its encoder differs, since the denoiser's
    latents are that encoder's."""
    run, out = Path(run), Path(out)
    if stage is None:
        stage = "cm" if (run / "cm").is_dir() or not (run / "diffusion").is_dir() else "diffusion"
    sampler = sampler_for_stage(stage)  # the one that samples what this stage trains
    if sampler is None:
        raise MlctError(f"cannot export stage '{stage}'; choose cm or diffusion")
    found = latest_checkpoint(run / stage / "checkpoints")
    if found is None:
        raise MlctError(f"{run / stage}: no checkpoint to export (train it first)")
    ckpt = load_checkpoint(found, with_state=False)
    # A checkpoint another tool (or a damaged run) wrote may lack what a bundle needs: one
    # line naming it, not a KeyError.
    missing = [k for k in META_KEYS if k not in ckpt.meta]
    if missing:
        raise MlctError(f"{found}: not a {stage} checkpoint (no {', '.join(missing)} in its "
                        f"metadata)")
    if not {"mean", "std"} <= ckpt.module_state("norm").keys():
        raise MlctError(f"{found}: holds no normalization (norm.mean, norm.std)")
    ae = ckpt.module_state("ae")
    config = ckpt.meta["config"]
    if decoder_from is not None:
        ae, widths = _same_encoder(ae, decoder_from)
        # a decoder narrower than its encoder (ae.decoder_channels): the bundle builds it so
        config = {**config, "ae": {**config["ae"], **widths}}
    decoder = {k: v for k, v in ae.items() if not k.startswith(ENCODER_PREFIXES)}
    target = strip_prefix(ckpt.tensors, "target")
    if stage == "cm":
        # the EMA target network when trained with one, else the online weights
        denoiser = (strip_prefix(target, "module.net") if target
                    else strip_prefix(ckpt.tensors, "denoiser"))
    else:
        denoiser = strip_prefix(target, "module")
    if not denoiser:
        raise MlctError(f"{found}: holds no {stage} denoiser weights")
    encoder = {k: v for k, v in ae.items() if k.startswith(ENCODER_PREFIXES)}
    tensors = {**{f"decoder.{k}": v for k, v in decoder.items()},
               # shipped for `mlct train ae --init MODEL_DIR` (fine-tuning); generation skips it
               **{f"{ENCODER_KEY}.{k}": v for k, v in encoder.items()},
               **{f"denoiser.{k}": v for k, v in denoiser.items()},
               "norm.mean": ckpt.tensors["norm.mean"], "norm.std": ckpt.tensors["norm.std"]}
    if half:  # float16 storage halves the file; loading casts back to float32
        tensors = {k: (v.half() if v.is_floating_point() and not k.startswith("norm.") else v)
                   for k, v in tensors.items()}
    meta = {"format": BUNDLE_FORMAT, "version": BUNDLE_VERSION, "sampler": sampler.name,
            "step": ckpt.meta["step"], "config": config,
            "feature_dim": ckpt.meta["feature_dim"], "skeleton": ckpt.meta["skeleton"],
            "text_encoder": ckpt.meta["text_encoder"], "text_dim": ckpt.meta["text_dim"]}
    if decoder_from is not None:
        meta["decoder_from"] = str(decoder_from)
    with atomic_dir(out) as tmp:
        _save_weights(tmp / "model.safetensors", tensors)
        (tmp / "config.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
        np.save(tmp / "Mean.npy", ckpt.tensors["norm.mean"].numpy())
        np.save(tmp / "Std.npy", ckpt.tensors["norm.std"].numpy())
        if onnx:  # inside: a failed export leaves no bundle behind
            (tmp / ONNX_DIR).mkdir()
            write_onnx_graphs(tmp, tmp / ONNX_DIR)
    return out


def _same_encoder(ae: dict, decoder_from: str | os.PathLike) -> tuple[dict, dict]:
    """The autoencoder state of decoder_from (a run, its ae/ stage or a checkpoint), checked to
    hold exactly the encoder of `ae`, and its decoders' widths (ae.decoder_channels,
    ae.arm_decoder_channels)."""
    path = Path(decoder_from)
    for checkpoints in (path / "ae" / "checkpoints", path / "checkpoints"):
        if checkpoints.is_dir() and (found := latest_checkpoint(checkpoints)) is not None:
            path = found
            break
    other_checkpoint = load_checkpoint(path, with_state=False)
    other = other_checkpoint.module_state("ae")
    other_ae = other_checkpoint.meta.get("config", {}).get("ae", {})
    widths = {key: int(other_ae.get(key, 0))
              for key in ("decoder_channels", "arm_decoder_channels")}
    encoder = [k for k in ae if k.startswith(ENCODER_PREFIXES)]
    # equal up to float16 storage: an --init from a --half bundle starts from rounded weights
    if not encoder or any(k not in other or other[k].shape != ae[k].shape
                          or not torch.allclose(other[k].float(), ae[k].float(), rtol=1e-3,
                                                atol=1e-5)
                          for k in encoder):
        raise MlctError(f"{decoder_from}: its encoder is not the run's, so the denoiser's "
                        f"latents would mean nothing to its decoder; train it with "
                        f"ae.freeze_encoder=true from this model (--init)")
    return other, widths


def bundle_with_decoder(model_dir: str | os.PathLike, decoder_from: str | os.PathLike,
                        out: str | os.PathLike) -> Path:
    """`mlct convert MODEL_DIR --decoder-from RUN --out DIR`: a copy of the bundle whose decoder
    is RUN's (an autoencoder trained on the bundle's frozen encoder, `train ae --init MODEL_DIR
    ae.freeze_encoder=true`, perhaps narrower: ae.decoder_channels), everything else as it was:
    the denoiser, the critic, the durations and the text anchors read only the text and the
    latents, whose meaning the frozen encoder keeps. `export --decoder-from` does the same
    from a stage-2 run; this needs only the model. The decoder is stored in the bundle's own
    precision (float16 for a --half bundle). ONNX graphs: `convert_to_onnx(out)` after."""
    from mlct.generate.bundle import BUNDLE_FILES, CONFIG, OPTIONAL_FILES, WEIGHTS, read_bundle
    from mlct.io import check_writable_dir

    model_dir, out = Path(model_dir), Path(out)
    _, tensors = read_bundle(model_dir)  # a bundle, or one line saying what is wrong
    if out.exists() and out.resolve() == model_dir.resolve():
        raise MlctError(f"{out} is the model itself: give --out a new directory")
    check_writable_dir(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise MlctError(f"{out} exists and is not empty; give --out a new or empty directory")
    encoder = strip_prefix(tensors, ENCODER_KEY)
    if not encoder:
        raise MlctError(f"{model_dir}: this model ships no autoencoder encoder (exported by an "
                        f"older mlct), so no decoder can be checked against it")
    ae, widths = _same_encoder(encoder, decoder_from)
    raw = load_file(str(model_dir / WEIGHTS))  # as stored: float16 where the bundle is --half
    stored = next(v.dtype for k, v in raw.items() if k.startswith("decoder."))
    kept = {k: v for k, v in raw.items() if not k.startswith("decoder.")}
    decoder = {f"decoder.{k}": v.to(stored) for k, v in ae.items()
               if not k.startswith(ENCODER_PREFIXES)}
    meta = json.loads((model_dir / CONFIG).read_text(encoding="utf-8"))
    meta["config"] = {**meta["config"], "ae": {**meta["config"]["ae"], **widths}}
    meta["decoder_from"] = str(decoder_from)
    with atomic_dir(out) as tmp:
        _save_weights(tmp / WEIGHTS, {**kept, **decoder})
        (tmp / CONFIG).write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
        for name in BUNDLE_FILES + OPTIONAL_FILES:
            if name not in (CONFIG, WEIGHTS) and (model_dir / name).is_file():
                shutil.copy2(model_dir / name, tmp / name)
    return out


def _save_weights(path: Path, tensors: dict[str, torch.Tensor]) -> None:
    """A bundle's model.safetensors, readable as the user's umask allows."""
    save_file({k: v.contiguous() for k, v in tensors.items()}, str(path),
              metadata={"format": BUNDLE_FORMAT})
    readable_by_umask(path)
