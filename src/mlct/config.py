"""Typed configuration: YAML presets, key=value overrides, one validated tree.

Every setting of a run lives here with its default and the paper's reason; a run saves the full
tree next to its weights, so the checkpoint alone rebuilds the model. Validation is pydantic's:
an unknown key or a value of the wrong type is one clear line, never a silent default.
"""

from __future__ import annotations

import copy
from importlib import resources
from pathlib import Path
from typing import Any, Literal, Sequence

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from mlct.errors import MlctError, first_line

PRESETS = ("humanml3d", "kit", "small", "tiny")
STAGES = ("ae", "cm", "diffusion")


class _Section(BaseModel):
    # Strict about names (a typo is an error), lenient about "1" vs 1 only where YAML is.
    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False)


class DataConfig(_Section):
    """How the dataset is read (the standard Text2MotionDatasetV2 protocol)."""

    max_motion_length: int = Field(196, ge=4)  # frames after padding
    unit_length: int = Field(4, ge=1)  # crops are multiples of this
    num_workers: int = Field(0, ge=0)  # DataLoader workers
    on_bad_file: Literal["strict", "skip"] = "strict"

    @model_validator(mode="after")
    def _crop_fits(self) -> DataConfig:
        if self.unit_length > self.max_motion_length:  # else the dataset refuses with a traceback
            raise ValueError(f"unit_length ({self.unit_length}) exceeds max_motion_length "
                             f"({self.max_motion_length})")
        return self


class TextConfig(_Section):
    """Frozen text encoder (Sec. 5: CLIP ViT-L/14; our default, the bundled MiniLM)."""

    encoder: str = "minilm"  # "minilm" | "clip:DIR" | "st:DIR" | DIR
    cache_dir: str | None = None  # embedding cache; None = $MLCT_CACHE or ~/.cache/mlct


class AutoencoderConfig(_Section):
    """Stage 1: skip-transformer motion autoencoder (Sec. 4.1, Eq. 7-9)."""

    latent_type: Literal["quantized", "vae", "plain"] = "quantized"
    n_tokens: int = Field(3, ge=1)  # n learnable latent tokens
    latent_dim: int = Field(256, ge=1)  # d
    levels: int = Field(1000, ge=1)  # l: 2l + 1 levels per dimension (Eq. 8)
    layers: int = Field(7, ge=1)  # odd: in blocks, middle, out blocks
    heads: int = Field(8, ge=1)
    ff_dim: int = Field(1024, ge=1)
    dropout: float = Field(0.1, ge=0.0, lt=1.0)
    joint_weight: float = Field(1e-3, ge=0.0)  # lambda_j (Eq. 9)
    # Ours: the smooth-L1 beta of the joint term, in metres. 1 (the default) is quadratic for
    # any error a body makes, so a 15 cm miss of a clapping hand costs ~0.01; a few cm makes
    # the term L1-like, so such misses cost their size (docs/training.md).
    joint_beta: float = Field(1.0, gt=0.0)
    kl_weight: float = Field(1e-4, ge=0.0)  # for latent_type = vae (MLD's value)
    # Ours, beyond Eq. 9 (0 / off = the paper): see nn/autoencoder.py and train/stages.py.
    # "transformer" = the paper's skip transformer; "conv" = nn/conv_autoencoder.py
    architecture: Literal["transformer", "conv"] = "transformer"
    channels: int = Field(128, ge=1)  # conv only: width of its 1-D convolutions
    # conv only: the last arm_tokens of the n tokens encode and decode the arm joints' features
    # by a pair of their own, arm_channels wide (0 = one pair for everything; nn/conv_autoencoder.py)
    arm_tokens: int = Field(0, ge=0)
    arm_channels: int = Field(64, ge=1)
    # conv only: the decoders' widths, when narrower than their encoders' (0 = channels and
    # arm_channels). Why: at batch 1 the decoder's time is its channels (2.7 ms at 128 / 128,
    # 0.95 at 64 / 64; docs/performance.md); trained on a
    # frozen encoder (freeze_encoder), the latents and the stage 2 on them stay as they are.
    decoder_channels: int = Field(0, ge=0)
    arm_decoder_channels: int = Field(0, ge=0)
    # how such a narrower decoder starts under `train ae --init`: "prune" = the model's own
    # decoder with its weakest channels removed (nn/narrow.py), "fresh" = new weights
    decoder_init: Literal["prune", "fresh"] = "prune"
    # an arm pair added by `train ae --init MODEL` starts "fresh" or as a copy of the model's
    # own pair restricted to the arms' columns, "body" (nn/grow.py arm_pair_from_body)
    arm_init: Literal["fresh", "body"] = "fresh"
    # conv only: hidden width of a two-layer MLP between the coarse grid and the tokens, both
    # ways (0 = one Linear each way, as before; nn/conv_autoencoder.py "bottleneck")
    bottleneck: int = Field(0, ge=0)
    # conv only: token i encodes and draws the i-th stretch of the clip (a time series of
    # tokens) instead of every token the whole clip (nn/conv_autoencoder.py "temporal")
    temporal: bool = False
    # conv only: stride-2 stages, each halving the time axis: 3 = a grid cell per 8 frames (0.4 s
    # at 20 fps), 2 = per 4. Why: a sway, a rope jump's hops or a nod repeat faster than two
    # cells of 0.4 s, so the coarse grid has to carry each swing inside a cell's channels
    # (nn/conv_autoencoder.py)
    stages: int = Field(3, ge=1, le=4)
    velocity_weight: float = Field(0.0, ge=0.0)  # frame-to-frame feature differences
    # The root's heading (radians) and ground path (metres), integrated from the per-frame
    # velocities: a small per-frame bias the feature loss shrugs at sums to a short turn
    # (the decoder turned 0.91 of the data's heading; docs/training.md "Turning by the angle").
    trajectory_weight: float = Field(0.0, ge=0.0)
    frame_upsampler: bool = False  # transformer only: the latent reaches every frame query
    # Decoder-only training (train/stages.py): the encoder's weights stay as loaded (--init), so
    # a stage-2 model trained on its latents stays valid with the new decoder.
    freeze_encoder: bool = False
    # Keep the arm pair's decoder as loaded (--init) too, while a narrower body decoder trains
    # (ae.decoder_channels). Why: trained along, the arm decoder drifted and claps fell from
    # 0.98 to 0.93 of the read-outs (docs/training.md).
    freeze_arm_decoder: bool = False
    # Fraction of each batch whose decoding target runs past the clip, the last pose held still
    # for a random number of frames: teaches the decoder what to draw after an action ends.
    hold_extension: float = Field(0.0, ge=0.0, le=1.0)
    # Std of Gaussian noise added to the latent before decoding, in training only (ours). Why:
    # latent noise of 0.13 (a third of a token's spread) turned 85 % of the bundled decoder's
    # claps and half its waves into damped swings that never meet or sway (bench: a stage-2
    # sample lies about that far from the latent of a real motion), while gaits survived
    # it: the arms' oscillations lived in the latent's finest detail. Trained with noise, the
    # encoder has to spread them over what the noise cannot hide (the latent is bounded in
    # [-1, 1], so it cannot simply grow).
    latent_noise: float = Field(0.0, ge=0.0)
    # Set by `train ae --init MODEL ae.n_tokens=N` when N exceeds the model's token count (that
    # count; 0 = not grown; nn/grow.py). With freeze_encoder, the encoder's rows of those first
    # tokens stay frozen and only the new tokens' rows train, so their latents keep their meaning.
    grown_from: int = Field(0, ge=0)


class DenoiserConfig(_Section):
    """Stage 2 network F: skip transformer, text + time added at every block (Sec. 4.2)."""

    width: int = Field(512, ge=1)
    layers: int = Field(11, ge=1)
    heads: int = Field(8, ge=1)
    ff_dim: int = Field(2048, ge=1)
    dropout: float = Field(0.1, ge=0.0, lt=1.0)
    # Ours (False = the authors'): the text + time condition goes into every token at every
    # block, not the condition token alone (nn/denoiser.py).
    condition_all_tokens: bool = False


class ScheduleConfig(_Section):
    """VP schedule (Eq. 10), Karras time grid (App. B), consistency parameterization (Eq. 11)."""

    beta_min: float = Field(0.1, ge=0.0)  # b0: authors' code; the paper prints 0.002
    beta_max: float = Field(20.0, gt=0.0)  # b1: authors' code; the paper prints 1
    num_steps: int = Field(50, ge=2)  # N points of the time grid
    eps: float = Field(0.002, gt=0.0)  # first grid time
    t_max: float = Field(1.0, gt=0.0)  # T
    rho: float = Field(2.0, gt=0.0)
    eta: float = Field(0.5, gt=0.0)  # sigma_data-like constant of c_skip / c_out
    time_scale: float = Field(10.0, gt=0.0)  # the 10 in c_skip = eta^2 / ((10 t)^2 + eta^2)
    # Ours (1 = the paper): stage 2 sees the AE latent times this factor, and samples are divided
    # by it before decoding. Why: a latent much smaller than the noise (std 0.34 for the small
    # conv AE) has a low signal-to-noise ratio at every t, and a short stage 2 regressed to the
    # mean latent (generated std 0.13-0.23 across prompts); Stable Diffusion's scale factor.
    latent_scale: float = Field(1.0, gt=0.0)


class ConsistencyConfig(_Section):
    """Conditionally guided consistency training (Eq. 13-15, Algorithm 1) and its sampler."""

    guidance: float = Field(1.0, ge=0.0)  # w: 1 for HumanML3D, 2 for KIT; 0 = vanilla CT
    uncond_weight: float = Field(1.0, ge=0.0)  # lambda_c
    # Ours (0 = the paper): weight of the direct term d(S(x_t, t, c), x_phi), see
    # diffusion/losses.py: the conditional branch also regresses the guided clean latent.
    denoise_weight: float = Field(0.0, ge=0.0)
    # Ours (None = every t): the direct term only where t_i <= this; at large t its best answer
    # is the text's median latent, which pulls every seed of a prompt to one motion.
    denoise_max_t: float | None = Field(None, gt=0.0)
    # Ours (0 = off): the same direct term measured on the motion, through the frozen decoder:
    # smooth-L1 between D(S(x_t, t, c)) and D(x_phi). The latent metric weighs every direction
    # alike, so stage 2 drew the mean count of an arm's oscillation (claps, waves: the latent's
    # small directions); the decoded metric weighs each as much as it moves the body.
    motion_weight: float = Field(0.0, ge=0.0)
    # Items of each batch decoded for it: decoding costs more than the denoiser's step, so a
    # random share of the batch carries the term (batches are shuffled: the first items).
    motion_items: int = Field(8, ge=1)
    # Ours (0 = off): Gaussian noise added to each training text vector, its size relative to
    # the vector's norm (0.5: cosine ~0.89 to the clean one). A paraphrase the model never
    # saw lands near, not on, a training caption's vector; the noise trains the neighbourhood.
    text_noise: float = Field(0.0, ge=0.0)
    # Its shape: "isotropic" (the size above is a share of each vector's norm) or "captions":
    # drawn from how one motion's captions differ from their mean (the size is a multiple of
    # that spread), so it moves a vector as a rephrasing does, not across an angle or a count.
    text_noise_shape: Literal["isotropic", "captions"] = "isotropic"
    huber_c: float = Field(0.001, gt=0.0)  # gamma of the pseudo-Huber metric
    target: Literal["ema", "online"] = "ema"  # EMA target network or online stop-gradient
    target_decay: float = Field(0.995, ge=0.0, lt=1.0)  # EMA rate of the target network
    nfe: int = Field(5, ge=1)  # default sampling steps (Algorithm 2)


class DiffusionConfig(_Section):
    """The MLD-style latent diffusion baseline: x0 prediction, condition dropout, DDIM + CFG."""

    cond_dropout: float = Field(0.1, ge=0.0, le=1.0)
    sample_steps: int = Field(50, ge=1)
    guidance: float = Field(7.5, ge=0.0)  # classifier-free guidance scale (two passes per step)
    ema_decay: float = Field(0.999, ge=0.0, lt=1.0)  # averaged weights exported for sampling


class TrainConfig(_Section):
    """Optimization of one stage."""

    batch_size: int = Field(64, ge=1)  # global batch; split across DDP ranks
    lr: float = Field(1e-4, gt=0.0)  # AdamW (Sec. 5)
    lr_min: float = Field(1e-6, ge=0.0)  # cosine schedule floor
    weight_decay: float = Field(0.0, ge=0.0)
    max_steps: int = Field(1000, ge=1)
    grad_clip: float = Field(10.0, gt=0.0)  # gradient-norm clip (authors' code)
    log_every: int = Field(50, ge=1)
    val_every: int = Field(500, ge=1)
    val_batches: int = Field(8, ge=1)  # validation loss over this many fixed batches
    ckpt_every: int = Field(500, ge=1)
    # torch seeds with seed * 1000 + rank, which must fit its 64 bits; negative seeds are
    # refused as everywhere else in mlct.
    seed: int = Field(0, ge=0, le=2**53 - 1)
    # auto: bf16 autocast for the autoencoder on CUDA, fp32 elsewhere (train/loop.py:
    # autocast_precision; stage 2 in bf16 on a GPU diverged)
    precision: Literal["auto", "fp32", "bf16"] = "auto"
    # Ours: on a GPU, the whole step (the frozen encoder, forward, backward, clipping, AdamW,
    # the EMA) replayed from one CUDA graph, the motions held on the device
    # (train/captured_step.py); elsewhere the same fixed-shape step runs without a graph.
    cuda_graph: bool = False
    # Ours: a logged gradient norm 30x the run's early median is warned about (stderr and
    # log.jsonl); with this, the run also stops there (train/divergence.py)
    stop_on_divergence: bool = False


class StageTrainConfigs(_Section):
    ae: TrainConfig = TrainConfig()
    cm: TrainConfig = TrainConfig()
    diffusion: TrainConfig = TrainConfig()


class Config(_Section):
    """Everything a run needs, from data to sampling."""

    preset: str = "custom"
    data: DataConfig = DataConfig()
    text: TextConfig = TextConfig()
    ae: AutoencoderConfig = AutoencoderConfig()
    denoiser: DenoiserConfig = DenoiserConfig()
    schedule: ScheduleConfig = ScheduleConfig()
    consistency: ConsistencyConfig = ConsistencyConfig()
    diffusion: DiffusionConfig = DiffusionConfig()
    train: StageTrainConfigs = StageTrainConfigs()

    def to_dict(self) -> dict[str, Any]:
        return self.model_dump(mode="json")


def _format_error(err: ValidationError, source: str) -> str:
    first = err.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    kind = first["type"]
    if kind == "extra_forbidden":
        return f"{source}: unknown config key '{where}'"
    value = first.get("input")
    message = first["msg"].removeprefix("Value error, ")  # a cross-field check's own words
    return f"{source}: bad value for '{where}': {message} (got {value!r})"


def config_from_dict(data: dict[str, Any], source: str = "config") -> Config:
    """Validate a nested dict into a Config; one-line MlctError on unknown keys or bad types."""
    if not isinstance(data, dict):
        raise MlctError(f"{source}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return Config.model_validate(data)
    except ValidationError as err:
        raise MlctError(_format_error(err, source)) from None


def preset_path(name: str) -> Path:
    if name not in PRESETS:
        raise MlctError(f"unknown preset '{name}'; choose one of {', '.join(PRESETS)}")
    return Path(str(resources.files("mlct") / "configs" / f"{name}.yaml"))


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise MlctError(f"cannot read config {path}: {err.strerror}") from None
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as err:
        raise MlctError(f"{path}: not valid YAML ({first_line(err)})") from None
    if not isinstance(data, dict):
        raise MlctError(f"{path}: expected a mapping at the top level")
    return data


def _merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def parse_override(item: str) -> tuple[list[str], Any]:
    """'a.b.c=value' -> (['a', 'b', 'c'], value parsed as YAML, so 1e-4, true, [1, 2] work)."""
    key, sep, raw = item.partition("=")
    if not sep or not key.strip():
        raise MlctError(f"override '{item}' is not of the form key=value")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:
        value = raw
    return key.strip().split("."), value


def apply_overrides(data: dict[str, Any], overrides: Sequence[str]) -> dict[str, Any]:
    out = copy.deepcopy(data)
    for item in overrides:
        path, value = parse_override(item)
        node = out
        for part in path[:-1]:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise MlctError(f"override '{item}': '{part}' is a value, not a section")
            node = child
        node[path[-1]] = value
    return out


def load_config(preset_or_file: str | Path | None = None,
                overrides: Sequence[str] = ()) -> Config:
    """A preset name or YAML file (which may name a `base` preset), then key=value overrides."""
    data: dict[str, Any] = {}
    source = "config"
    if preset_or_file is not None:
        name = str(preset_or_file)
        path = preset_path(name) if name in PRESETS else Path(name)
        if name not in PRESETS and not path.exists():
            raise MlctError(f"config '{name}' is neither a preset ({', '.join(PRESETS)}) "
                            f"nor an existing file")
        data = _read_yaml(path)
        source = str(path)
        base = data.pop("base", None)
        if base is not None:
            data = _merge(_read_yaml(preset_path(str(base))), data)
    data = apply_overrides(data, overrides)
    return config_from_dict(data, source if not overrides else f"{source} + overrides")
