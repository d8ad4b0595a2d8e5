"""`mlct export-web`: a model as a static web site that generates motions in the browser.

    mlct export-web --model bundled --out SITE/
    python -m http.server -d SITE/ 8000    # any static file server; no Python model runs

SITE/ holds
- index.html, app.js, style.css and the page's modules (static/: the tokenizer, the portable
  noise, the model pipeline, features -> joints, the BVH and GLB writers, the 3D view);
- model/: text_encoder.onnx.gz (MiniLM, int8, gzipped: pack.py), denoiser.onnx and
  decoder.onnx (the onnx backend's graphs, weights stored as float16: the same numbers;
  generate/backends/onnx/compact.py), vocab.txt (the WordPiece vocabulary) and model.json (sampler
  times and constants, normalisation statistics, skeleton and rest pose, sizes);
- vendor/: onnxruntime-web's WASM runtime (its binary gzipped) and three, from the npm
  packages that vendor.py pins.

The browser runs what the onnx backend runs (generate/backends/onnx/networks.py): tokenizer, text
encoder, the consistency sampler around the denoiser (Algorithm 2), the decoder, the
denormalisation and features -> joints, with the noise of generate/samplers/portable_noise.py in place
of torch's, and makes a prompt as generate() makes it (split, re-attached, kept going, best of
N), so `load_site_reference` and reference.py give the page's joints in Python (the end-to-end
test).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path
from typing import Any

import torch

from mlct.errors import MlctError
from mlct.generate.bundle import read_bundle
from mlct.generate.compose.actions import portable_rules
from mlct.generate.compose.critic import MAX_CANDIDATES, Critic
from mlct.generate.control.schema import part_joints
from mlct.generate.compose.durations import FASTEST_TEMPO_SHARE, MIN_WEIGHT, read_durations
from mlct.generate.compose.keep_going import portable_rules as portable_keep_going
from mlct.generate.compose.long_motion import BLEND_SECONDS
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.load import onnx_generator
from mlct.generate.backends.onnx.bundle import OnnxGraphs, weights_digest
from mlct.generate.backends.onnx.convert import write_onnx_graphs
from mlct.generate.backends.onnx.compact import (float16_storage, quantize_int8,
                                        quantize_int8_weights, require_onnx)
from mlct.generate.compose.lengths import DEFAULT_SECONDS, MAX_GAIT_SECONDS, MIN_PART_SECONDS
from mlct.generate.seeds import MAX_SEED, SEED_STRIDE
from mlct.generate.bundle import bundled_model_dir
from mlct.generate.compose.prompts import MAX_PROMPT_CHARS, portable_stated
from mlct.generate.samplers import ConsistencySampler, sampler_class
from mlct.io import atomic_dir, check_writable_dir, read_format_json
from mlct.motion.foot_lock import ANKLE_HEIGHT, FootLock
from mlct.motion.skeleton import get_skeleton
from mlct.onnx_io import export_graph, onnxruntime_module
from mlct.text.encoders import bundled_minilm_path, token_slots_of
from mlct.text.minilm import check_pipeline
from mlct.text.minilm_onnx import check_onnx_spec
from mlct.text.sides import SIDE_CONTRAST, SIDES_SUFFIX
from mlct.serve.site.pack import gzip_file, remove_with, unpacked
from mlct.serve.site.vendor import copy_vendor_files

STATIC = Path(__file__).resolve().parent / "static"
MODEL_DIR = "model"  # in the site
SITE_JSON = "model.json"
SITE_FORMAT, SITE_VERSION = "mlct-web", 1
GRAPHS = {"text_encoder": "text_encoder.onnx", "denoiser": "denoiser.onnx",
          "decoder": "decoder.onnx"}
CRITIC_GRAPH = "critic.onnx"  # best-of-N in the page, for a model with a critic
VOCAB = "vocab.txt"
WASM = "ort-wasm-simd-threaded.wasm"  # in vendor/: what the page gives ONNX Runtime Web itself
# MiniLM's graph in the site (generate/backends/onnx/compact.py): int8 arithmetic (the fastest in the
# browser), int8 weights computed in float32 (closer to the float32 embeddings, several times
# slower in ONNX Runtime Web, which dequantizes them on every run), or MiniLM's float32 (90 MB)
TEXT_ENCODER_PRECISIONS = ("int8", "int8-weights", "float32")
# The denoiser's graph: float16 storage (the bundle's own numbers, 10 MB) or ONNX Runtime's
# dynamic int8 (5 MB, faster in the page; joints ~6 mm from float16's, docs/web.md)
DENOISER_PRECISIONS = ("float16", "int8")

# The tokenizer.json settings that static/tokenizer.js implements; another tokenizer is refused.
TOKENIZER = {"normalizer": {"type": "BertNormalizer", "clean_text": True,
                            "handle_chinese_chars": True, "strip_accents": None,
                            "lowercase": True},
             "pre_tokenizer": {"type": "BertPreTokenizer"}}
WORDPIECE = {"type": "WordPiece", "unk_token": "[UNK]", "continuing_subword_prefix": "##",
             "max_input_chars_per_word": 100}


def resolve_model(model: str | os.PathLike | None) -> Path:
    """A model directory, or the bundled model for None / 'bundled'."""
    return bundled_model_dir() if model is None or str(model) == "bundled" else Path(model)


def _tokenizer_settings(path: Path) -> dict[str, Any]:
    """The MiniLM tokenizer's settings for the page; MlctError unless tokenizer.js does them."""
    spec = json.loads((path / "tokenizer.json").read_text(encoding="utf-8"))
    model = {k: v for k, v in spec["model"].items() if k != "vocab"}
    if (spec.get("normalizer") != TOKENIZER["normalizer"]
            or spec.get("pre_tokenizer") != TOKENIZER["pre_tokenizer"]
            or any(model.get(k) != v for k, v in WORDPIECE.items())):
        raise MlctError(f"{path}/tokenizer.json is not the BERT WordPiece tokenizer that the "
                        f"web page implements")
    vocab = (path / VOCAB).read_text(encoding="utf-8").splitlines()
    if any(spec["model"]["vocab"].get(word) != i for i, word in enumerate(vocab)):
        raise MlctError(f"{path}/{VOCAB} does not match tokenizer.json's vocabulary")
    special = {t["content"]: t["id"] for t in spec.get("added_tokens", [])}
    return {"vocab": VOCAB, "special_tokens": special, "cls": special["[CLS]"],
            "sep": special["[SEP]"], "unk": special["[UNK]"],
            "max_input_chars_per_word": WORDPIECE["max_input_chars_per_word"]}


def site_description(meta: dict, tensors: dict[str, torch.Tensor], model_dir: Path,
                     tokenizer: dict[str, Any], latent_shape: tuple[int, int],
                     precision: str, denoiser: str,
                     stored: dict[str, str] | None = None,
                     critic: Critic | None = None) -> dict[str, Any]:
    """model.json: everything the page computes with, besides the graphs."""
    from mlct import __version__
    from mlct.config import config_from_dict

    config = config_from_dict(meta["config"], "model config")
    sampler = ConsistencySampler(config)
    skeleton = get_skeleton(meta["skeleton"])
    schedule = config.schedule
    spec = meta["text_encoder"].strip().lower()
    max_length = min(check_pipeline(bundled_minilm_path()), 512)
    return {
        "format": SITE_FORMAT, "version": SITE_VERSION, "mlct": __version__,
        "weights_sha256": weights_digest(model_dir),
        # the file names as stored: gzipped ones (pack.py) end in .gz; the page unpacks them
        "graphs": {k: (stored or {}).get(k, v) for k, v in GRAPHS.items()},
        "wasm": (stored or {}).get("wasm", WASM), "denoiser_precision": denoiser,
        "text_encoder": {"spec": spec, "precision": precision, "max_length": max_length,
                         "dim": meta["text_dim"], "token_slots": token_slots_of(spec),
                         # text/sides.py: e + alpha (e - e(mirror)) for 'minilm+sides', else 0
                         "side_contrast": SIDE_CONTRAST if spec.endswith(SIDES_SUFFIX) else 0.0,
                         **tokenizer},
        "sampler": {"name": sampler.name, "grid": [float(t) for t in sampler.grid],
                    "eta": schedule.eta, "time_scale": schedule.time_scale,
                    "beta_min": schedule.beta_min, "beta_max": schedule.beta_max,
                    "clamp": sampler.clamp, "default_nfe": sampler.default_steps,
                    "max_nfe": sampler.max_steps},
        "latent_shape": list(latent_shape), "latent_scale": schedule.latent_scale,
        "feature_dim": meta["feature_dim"], "max_frames": config.data.max_motion_length,
        "max_prompt_chars": MAX_PROMPT_CHARS,
        "norm": {"mean": tensors["norm.mean"].float().tolist(),
                 "std": tensors["norm.std"].float().tolist()},
        "skeleton": {"name": skeleton.name, "unit": skeleton.unit, "fps": skeleton.fps,
                     "joint_names": list(skeleton.joint_names),
                     "parents": list(skeleton.parents),
                     # the rest pose of the page's BVH fit (static/bvh.js, as motion/rigfit.py)
                     "rest_directions": skeleton.rest_directions.tolist(),
                     "foot_left": list(skeleton.foot_left),
                     "foot_right": list(skeleton.foot_right),
                     # hips and shoulders, the facing a chain of parts turns by (static/chain.js)
                     "face_joints": list(skeleton.face_joints),
                     # the joints an arm action done during another is put on the body with
                     # (compose.parts.concurrent: control.fit.reattach; static/chain.js)
                     "arm_joints": list(part_joints("arms", skeleton))},
        # planted feet (motion/foot_lock.py; static/motion.js: lockFeet), as generate() does
        "foot_lock": {**dataclasses.asdict(FootLock()), "ankle_height": ANKLE_HEIGHT},
        # a prompt that names actions in turn, made one part each and chained, as generate()
        # does (static/compose.js: generate/compose/actions.py's rules; static/chain.js: compose/long_motion.py)
        "sequence": {"rules": portable_rules(), "min_part_seconds": MIN_PART_SECONDS,
                     "blend_seconds": BLEND_SECONDS},
        # a gait asked for longer than it lasts keeps going (generate/compose/keep_going.py; keepgoing.js)
        "keep_going": {**portable_keep_going(), "max_gait_seconds": MAX_GAIT_SECONDS},
        # "... for 8 seconds": the clip's length, the phrase taken out (prompts.stated_seconds)
        "stated": portable_stated(),
        # a clip's length when the page is not given one (compose.timing.default_seconds)
        "default_seconds": DEFAULT_SECONDS,
        "durations": _portable_durations(model_dir, meta),
        # one of the best of N by the critic (generate/compose/critic.py, MotionGenerator.sample_best):
        # its graph, the model's N and margin, and how candidate k's seed comes from the
        # motion's (64-bit: strings)
        "critic": None if critic is None else {
            "graph": (stored or {}).get("critic", CRITIC_GRAPH), "candidates": critic.candidates,
            "margin": critic.margin,
            "max_candidates": MAX_CANDIDATES, "seed_stride": str(SEED_STRIDE),
            "seed_modulus": str(MAX_SEED + 1)},
    }


def _write_critic_graph(critic: Critic, path: Path) -> Path:
    """The model's critic (generate/compose/critic.py) as an ONNX graph (z, frames, text) -> score, for
    the page's best-of-N: z the (B, n, d) latents over latent_scale, frames (B,) float."""
    class Score(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.network = critic.network

        def forward(self, z: torch.Tensor, frames: torch.Tensor, text: torch.Tensor
                    ) -> torch.Tensor:
            return self.network.score(z, frames, text)

    probe = torch.Generator().manual_seed(0)
    z = torch.randn(2, 1, critic.network.latent_size, generator=probe)
    text = torch.randn(2, critic.network.text_dim, generator=probe)
    batch = {0: "batch"}
    return export_graph(Score(), (z, torch.tensor([40.0, 80.0]), text), path,
                        ("z", "frames", "text"), ("score",),
                        {"z": batch, "frames": batch, "text": batch, "score": batch})


def _portable_durations(model_dir: Path, meta: dict) -> dict[str, Any] | None:
    """The model's duration model (generate/compose/durations.py) for the page's parts' shares, without
    its fit's record; None when the model has none (the parts then share alike)."""
    model = read_durations(model_dir, meta["text_encoder"], int(meta["text_dim"]))
    if model is None:
        return None
    return {**{k: v for k, v in model.to_json().items() if k != "fit"},
            "min_weight": MIN_WEIGHT, "fastest_tempo_share": FASTEST_TEMPO_SHARE}


def export_site(model: str | os.PathLike | None, out: str | os.PathLike,
                vendor: str | os.PathLike | None = None, text_encoder: str = "int8-weights",
                denoiser: str = "float16", gzip: bool = True) -> Path:
    """Write the static site of model (a directory, or None / 'bundled') to out; returns out.
    vendor: a folder holding the npm tarballs (vendor.py), instead of the cache.
    text_encoder: one of TEXT_ENCODER_PRECISIONS (int8 and int8-weights 23 MB, float32 90 MB);
    denoiser: one of DENOISER_PRECISIONS; gzip: store the files that gzip makes much smaller
    (the int8 text encoder, the WASM binary) gzipped (pack.py: 36 MB instead of 52, the same
    numbers)."""
    for name, value, known in (("text_encoder", text_encoder, TEXT_ENCODER_PRECISIONS),
                               ("denoiser", denoiser, DENOISER_PRECISIONS)):
        if value not in known:
            raise MlctError(f"{name} must be one of {', '.join(known)}, got {value!r}")
    model_dir, out = resolve_model(model), Path(out)
    meta, tensors = read_bundle(model_dir)  # a bundle, or one line saying what is wrong
    if sampler_class(meta["sampler"]) is not ConsistencySampler:
        raise MlctError(f"{model_dir}: export-web runs consistency models (MLCT); this one "
                        f"samples with {meta['sampler']!r}")
    check_onnx_spec(meta["text_encoder"])
    onnxruntime_module()  # the graphs are written with onnx and checked with onnxruntime:
    require_onnx()  # their absence is said before the npm download
    tokenizer = _tokenizer_settings(bundled_minilm_path())
    check_writable_dir(out)
    if out.exists() and (not out.is_dir() or (any(out.iterdir())
                                              and not (out / MODEL_DIR / SITE_JSON).is_file())):
        raise MlctError(f"{out} exists and is not an mlct web site; give a new or empty "
                        f"directory to --out")
    with atomic_dir(out) as tmp:
        copy_vendor_files(tmp / "vendor", vendor)  # first: the likeliest to fail (network)
        folder = tmp / MODEL_DIR
        (tmp / "float32").mkdir()
        # standard operators only: ONNX Runtime Web runs the page's graphs
        graphs = write_onnx_graphs(model_dir, tmp / "float32", fused_text=False)
        folder.mkdir()
        if denoiser == "int8":
            quantize_int8(graphs / GRAPHS["denoiser"], folder / GRAPHS["denoiser"],
                          ("MatMul", "Gemm"))
        else:
            float16_storage(graphs / GRAPHS["denoiser"], folder / GRAPHS["denoiser"])
        float16_storage(graphs / GRAPHS["decoder"], folder / GRAPHS["decoder"])
        if text_encoder == "int8":
            quantize_int8(graphs / GRAPHS["text_encoder"], folder / GRAPHS["text_encoder"])
        elif text_encoder == "int8-weights":
            quantize_int8_weights(graphs / GRAPHS["text_encoder"],
                                  folder / GRAPHS["text_encoder"])
        else:
            shutil.copyfile(graphs / GRAPHS["text_encoder"], folder / GRAPHS["text_encoder"])
        shutil.copyfile(bundled_minilm_path() / VOCAB, folder / VOCAB)
        generator = onnx_generator(meta, tensors, _graphs(folder))
        latent = generator.ae.latent_shape
        if generator.critic is not None:  # float16 storage: the critic's own float16 numbers
            float16_storage(_write_critic_graph(generator.critic, graphs / CRITIC_GRAPH),
                            folder / CRITIC_GRAPH)
        shutil.rmtree(graphs)
        stored = {key: name for key, name in GRAPHS.items()} | {"wasm": WASM}
        if gzip:  # the files that gzip makes much smaller (pack.py)
            stored = {key: gzip_file((tmp / "vendor" if key == "wasm" else folder) / name).name
                      for key, name in stored.items()}
        if (folder / CRITIC_GRAPH).is_file():
            stored["critic"] = (gzip_file(folder / CRITIC_GRAPH).name if gzip else CRITIC_GRAPH)
        description = site_description(meta, tensors, model_dir, tokenizer, latent,
                                       text_encoder, denoiser, stored, generator.critic)
        (folder / SITE_JSON).write_text(json.dumps(description) + "\n", encoding="utf-8")
        for item in STATIC.iterdir():
            if item.is_file():
                shutil.copyfile(item, tmp / item.name)
    return out


def _graphs(folder: Path) -> OnnxGraphs:
    return OnnxGraphs(*(folder / GRAPHS[k] for k in ("text_encoder", "denoiser", "decoder")),
                      manifest={})


def load_site_reference(site: str | os.PathLike, model: str | os.PathLike | None = None,
                        threads: int | None = None) -> MotionGenerator:
    """The onnx backend running the site's own graphs (the int8 text encoder included), for
    the model the site was made from: what the page computes, in Python. With
    serve.site.reference.generate_with_portable_noise, the page's motion for a seed."""
    folder = Path(site) / MODEL_DIR
    if not (folder / SITE_JSON).is_file():
        raise MlctError(f"{site}: not an mlct web site (no {MODEL_DIR}/{SITE_JSON})")
    description = read_format_json(folder / SITE_JSON, SITE_FORMAT, SITE_VERSION,
                                   "an mlct web site's model description")
    model_dir = resolve_model(model)
    if description.get("weights_sha256") != weights_digest(model_dir):
        raise MlctError(f"{site} was exported from another model than {model_dir}")
    meta, tensors = read_bundle(model_dir)
    paths, scratch = unpacked({k: folder / v for k, v in description["graphs"].items()})
    graphs = OnnxGraphs(*(paths[k] for k in ("text_encoder", "denoiser", "decoder")),
                        manifest={})
    generator = onnx_generator(meta, tensors, graphs, threads=threads)
    remove_with(generator, scratch)  # the unpacked graphs live as long as the generator
    return generator


def site_size(site: str | os.PathLike) -> dict[str, int]:
    """Bytes per top-level entry of the site, and "total"."""
    site = Path(site)
    sizes = {item.name: (sum(f.stat().st_size for f in item.rglob("*") if f.is_file())
                         if item.is_dir() else item.stat().st_size) for item in site.iterdir()}
    sizes["total"] = sum(sizes.values())
    return sizes
