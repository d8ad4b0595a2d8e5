"""One training loop for every stage: read it top to bottom.

    mlct train ae|cm|diffusion --data DIR --out RUN [--config F] [key=value ...] [--resume]

RUN/<stage>/ holds config.yaml, log.jsonl, tb/ (TensorBoard) and checkpoints/. The same command
runs alone or under torchrun (DDP); only rank 0 writes.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import torch
import yaml
from torch import Tensor
from torch.nn.parallel import DistributedDataParallel

from mlct.config import Config, TrainConfig, apply_overrides, config_from_dict
from mlct.data.dataset import Text2MotionDataset
from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.io import write_text
from mlct.nn.dropout import use_cheap_dropout
from mlct.train import distributed
from mlct.train.batches import fixed_batches, step_loader
from mlct.train.captured_step import CapturedStep, optimizer_update, restore_optimizer
from mlct.train.checkpoint import (STATE, WEIGHTS, intact_checkpoints, latest_checkpoint,
                                   load_checkpoint, remove_partial_writes, resume_checkpoint,
                                   save_checkpoint)
from mlct.train.divergence import DivergenceWatch
from mlct.train.resident import ResidentMotions
from mlct.train.stages import (AutoencoderStage, ConsistencyStage, DiffusionStage, Stage,
                               TextTable, find_autoencoder)

STAGE_NAMES = ("ae", "cm", "diffusion")


class JsonlLog:
    """Append-only JSON lines; on resume, lines past the resumed step are dropped first."""

    def __init__(self, path: Path, resume_step: int | None) -> None:
        self.path = path
        if resume_step is not None and path.exists():
            kept = [line for line in path.read_text(encoding="utf-8").splitlines()
                    if line.strip() and json.loads(line).get("step", 0) <= resume_step]
            write_text(path, "".join(line + "\n" for line in kept))
        elif resume_step is None and path.exists():
            path.unlink()

    def write(self, record: dict[str, Any]) -> None:
        with self.path.open("a", encoding="utf-8") as handle:
            handle.write(json.dumps(record) + "\n")


def autocast_precision(precision: str, stage: str, device: torch.device) -> str:
    """'bf16' or 'fp32': what train.<stage>.precision asks for on this device. 'auto' is bf16
    autocast for the autoencoder on CUDA and fp32 everywhere else: stage 2 with bf16 autocast
    on a GPU (an H200, CUDA graphs, batches of 128, lr 1e-4) diverged in all three runs tried,
    its gradient norm going from ~20 to thousands after 2,750-3,250 steps, where the same seed
    in fp32 stayed at 16-21, for 15% fewer samples a second (docs/training.md). bf16 stage 2 on the
    CPU, asked for by name, trained the bundle."""
    if precision != "auto":
        return precision
    return "bf16" if device.type == "cuda" and stage == "ae" else "fp32"


def _autocast(device: torch.device, precision: str,
              cache: bool = True) -> contextlib.AbstractContextManager:
    """bf16 autocast when `precision` (autocast_precision's) says so. cache=False for a CUDA
    graph: autocast's cache of cast weights would outlive the capture
    (torch.cuda.make_graphed_callables says the same)."""
    if precision != "bf16":
        return contextlib.nullcontext()
    return torch.autocast(device_type=device.type, dtype=torch.bfloat16, cache_enabled=cache)


def _check_capturable(config: Config, stage: str, info: distributed.DistInfo) -> None:
    """What train.<stage>.cuda_graph cannot hold yet, refused before any work."""
    if info.enabled:
        raise MlctError(f"train.{stage}.cuda_graph runs in one process; DDP's gradient "
                        f"all-reduce is not captured: drop cuda_graph or run without torchrun")
    if stage == "cm" and config.consistency.motion_weight > 0:
        raise MlctError("train.cm.cuda_graph cannot hold consistency.motion_weight (its decode "
                        "is cut at each batch's longest item): set one of them to 0")


def _finite_loss(loss: Tensor, step: int, stage_dir: Path, info: distributed.DistInfo) -> None:
    """Stop the run on a non-finite loss (averaged over ranks), naming the last good checkpoint."""
    reduced = distributed.mean_over_ranks(loss.detach().float(), info)
    if not math.isfinite(float(reduced)):
        latest = latest_checkpoint(stage_dir / "checkpoints")
        raise MlctError(f"loss is {float(reduced)} at step {step}; training stopped. "
                        f"The last good checkpoint is {latest or 'none (none was saved)'}")


def _watch_divergence(watch: DivergenceWatch, record: dict[str, Any], stage: str,
                      precision: str, stop: bool, stage_dir: Path, log: JsonlLog | None,
                      info: distributed.DistInfo) -> None:
    """Warn once (stderr and log.jsonl) when the logged gradient norm leaves its early range;
    with train.<stage>.stop_on_divergence, stop there, naming the last checkpoint."""
    note = watch.check(record["step"], record["grad_norm"])
    if note is None:
        return
    if precision == "bf16":
        note += ("; this run trains in bf16, and stage 2 diverged in bf16 where fp32 did not "
                 f"(train.{stage}.precision=fp32)")
    if log is not None:
        log.write({"step": record["step"], "warning": note})
    if stop:
        latest = latest_checkpoint(stage_dir / "checkpoints")
        raise MlctError(f"{note}; training stopped (train.{stage}.stop_on_divergence). The "
                        f"last checkpoint is {latest or 'none (none was saved)'}")
    if info.is_main:
        print(f"mlct train: warning: {note}", file=sys.stderr)


def _autoencoder_stats(path: Path) -> tuple[Tensor, Tensor]:
    """Mean and Std an autoencoder checkpoint was trained with."""
    norm = load_checkpoint(path, with_state=False).module_state("norm")
    return norm["mean"].float(), norm["std"].float()


def _rng_state(device: torch.device) -> dict[str, Any]:
    state = {"torch": torch.get_rng_state()}
    if device.type == "cuda":
        state["cuda"] = torch.cuda.get_rng_state(device)
    return state


def _set_rng_state(state: dict[str, Any], device: torch.device) -> None:
    torch.set_rng_state(state["torch"])
    if device.type == "cuda" and "cuda" in state:
        torch.cuda.set_rng_state(state["cuda"], device)


def _resume_config(saved: dict[str, Any], overrides: list[str], stage: str) -> Config:
    """The saved config, plus overrides that may only touch this stage's train section
    (e.g. a larger max_steps); anything else would make the resumed run a different run."""
    for item in overrides:
        if not item.startswith(f"train.{stage}."):
            raise MlctError(f"--resume continues the saved config; only train.{stage}.* may be "
                            f"overridden, not '{item.split('=')[0]}'")
    return config_from_dict(apply_overrides(saved, overrides), "resumed config")


def _build_stage(stage: str, config: Config, run: Path, data: Text2MotionDataset,
                 val: Text2MotionDataset | None, info: distributed.DistInfo,
                 ae_path: str | Path | None) -> Stage:
    if stage == "ae":
        return AutoencoderStage(config, info.device, torch.from_numpy(data.mean),
                                torch.from_numpy(data.std), data.skeleton.name)
    from mlct.text import CachedTextEncoder, EmbeddingCache, default_cache_dir, load_text_encoder

    captions = data.captions() + (val.captions() if val is not None else [])
    cache_dir = Path(config.text.cache_dir) if config.text.cache_dir else default_cache_dir()
    # Rank 0 fills the disk cache first; the others then read it instead of encoding again.
    encoder = None
    for turn in ("main", "rest"):
        if (turn == "main") == info.is_main:
            encoder = CachedTextEncoder(load_text_encoder(config.text.encoder),
                                        EmbeddingCache(cache_dir))
            table = TextTable(encoder, captions, info.device)
        distributed.barrier(info)
    if config.consistency.text_noise > 0 and config.consistency.text_noise_shape == "captions":
        table.residuals = table.caption_residuals(
            [[record.caption for record in item.captions] for item in data.items])
    path = find_autoencoder(run, ae_path)
    cls = ConsistencyStage if stage == "cm" else DiffusionStage
    built = cls(config, info.device, path, table)
    if built.ae_meta["feature_dim"] != data.skeleton.feature_dim:
        raise MlctError(f"the autoencoder {path} reads {built.ae_meta['feature_dim']}-d motion, "
                        f"the data has {data.skeleton.feature_dim}-d features")
    return built


def _validate(stage: Stage, batches: list[dict], seed: int, device: torch.device,
              precision: str) -> dict[str, float]:
    """Mean loss terms over fixed batches, with a fixed generator: comparable across steps."""
    stage.train(False)
    generator = torch.Generator(device=device)
    generator.manual_seed(seed)
    sums: dict[str, float] = {}
    with torch.no_grad(), _autocast(device, precision):
        for batch in batches:
            for key, value in stage.loss(stage.trainable, batch, generator).items():
                sums[key] = sums.get(key, 0.0) + float(value)
    stage.train(True)
    return {f"val_{k}": v / len(batches) for k, v in sums.items()}


def _progress(total: int, start: int, enabled: bool, desc: str) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=start, disable=not enabled, desc=desc, dynamic_ncols=True,
                unit="it")


def train(stage: str, data_dir: str | Path, out: str | Path, config: Config | None = None,
          overrides: list[str] | None = None, resume: bool = False,
          ae_path: str | Path | None = None, device: str | None = None,
          progress: bool = True, stop_at: int | None = None,
          init: str | Path | None = None) -> dict[str, Any]:
    """Train one stage; returns a summary (final step, last losses, throughput, paths).

    init: a model bundle (`mlct export`) to start from, for fine-tuning on other data: its
    config (plus `overrides`), its normalization and its weights (the AE for `ae`, the denoiser
    for `cm` / `diffusion`). `config` is then ignored. For `ae` it may also be an autoencoder
    run (its latest checkpoint), to train on with other options.

    stop_at: leave after this step (checkpointed) as if interrupted; `resume` continues it
    exactly. For time-sliced jobs, and how the tests check exact resumption.
    """
    if stage not in STAGE_NAMES:
        raise MlctError(f"unknown stage '{stage}'; choose one of {', '.join(STAGE_NAMES)}")
    if config is not None and not isinstance(config, Config):
        raise TypeError(f"config must be a Config (mlct.config.load_config), not "
                        f"{type(config).__name__}")
    if isinstance(overrides, str):  # a string would be read as one override per character
        raise TypeError("overrides must be a list of 'key=value' strings, not one string")
    if resume and init is not None:
        raise MlctError("--init starts a new run from a model; --resume continues a run: "
                        "pass one of them")
    if stop_at is not None and stop_at < 1:
        raise MlctError(f"stop_at must be a step >= 1, got {stop_at}")
    run = Path(out)
    stage_dir = run / stage
    ckpt_dir = stage_dir / "checkpoints"
    overrides = list(overrides or [])
    info = distributed.setup(device)
    try:
        if info.is_main:
            remove_partial_writes(ckpt_dir)  # what a kill during a checkpoint write left
        try:
            found = latest_checkpoint(ckpt_dir)
        except MlctError:
            if not resume:
                raise
            found = None  # resume_checkpoint falls back to an intact one, or says why not
        checkpoint = None
        if resume:
            if found is None and not intact_checkpoints(ckpt_dir):
                raise MlctError(f"{ckpt_dir}: no checkpoint to resume from")
            checkpoint, note = resume_checkpoint(ckpt_dir)
            if note and info.is_main:
                print(f"mlct train: warning: {note}", file=sys.stderr)
            if checkpoint.meta.get("stage") != stage:
                raise MlctError(f"{found}: a '{checkpoint.meta.get('stage')}' checkpoint, "
                                f"not '{stage}'")
            config = _resume_config(checkpoint.meta["config"], overrides, stage)
        else:
            if found is not None:
                raise MlctError(f"{stage_dir} already holds a run; pass --resume to continue it "
                                f"or choose another --out")
            if init is not None:
                initial = InitialWeights.read(init, stage)
                base = initial.config
            else:
                base = config.to_dict() if config is not None else Config().to_dict()
            config = config_from_dict(apply_overrides(base, overrides), "config + overrides")
            if init is not None and stage == "ae":
                config = _record_growth(config, int(initial.config["ae"]["n_tokens"]))
        return _train(stage, Path(data_dir), run, config, checkpoint, info, ae_path, progress,
                      stop_at, initial if init is not None else None)
    finally:
        distributed.teardown(info)


def _adds_arm_pair(old: dict[str, Any], new: Config) -> bool:
    """Does `train ae --init` give a model without an arm pair one (nn/grow.py add_arm_pair)?"""
    if not new.ae.arm_tokens or int(old["ae"].get("arm_tokens", 0)):
        return False
    if new.ae.n_tokens != int(old["ae"]["n_tokens"]) + new.ae.arm_tokens:
        raise MlctError(f"an arm pair of {new.ae.arm_tokens} token(s) added to a model of "
                        f"{old['ae']['n_tokens']} needs ae.n_tokens="
                        f"{int(old['ae']['n_tokens']) + new.ae.arm_tokens}: its tokens become "
                        f"the body's")
    return True


def _narrows_decoder(old: dict[str, Any], new: Config) -> bool:
    """Does `train ae --init` give the model decoders of other widths (ae.decoder_channels,
    ae.arm_decoder_channels)? Those start pruned or fresh (ae.decoder_init); the encoders load
    as they were."""
    width = {key: int(old["ae"].get(key, 0)) or int(old["ae"].get(base, 0))
             for key, base in (("decoder_channels", "channels"),
                               ("arm_decoder_channels", "arm_channels"))}
    a = new.ae
    return ((a.decoder_channels or a.channels) != width["decoder_channels"]
            # an arm pair on both sides (one added by --init is nn/grow.py's, not this)
            or bool(a.arm_tokens and int(old["ae"].get("arm_tokens", 0)))
            and (a.arm_decoder_channels or a.arm_channels) != width["arm_decoder_channels"])


def _record_growth(config: Config, old_n: int) -> Config:
    """An autoencoder --init from a model with fewer latent tokens grows it (nn/grow.py): its
    config says from how many, so a resumed run freezes the same encoder rows (0 when the
    count stays: a model grown before is not grown again)."""
    grown = config.to_dict()
    if config.ae.n_tokens == old_n:
        grown["ae"]["grown_from"] = 0
        return config_from_dict(grown, "config + overrides")
    if config.ae.n_tokens < old_n:
        raise MlctError(f"ae.n_tokens={config.ae.n_tokens}: the model has {old_n} latent tokens, "
                        f"and a latent can grow, not shrink")
    if config.ae.architecture != "conv":
        raise MlctError("growing the latent (ae.n_tokens above the model's) needs the conv "
                        "autoencoder (ae.architecture: conv)")
    grown["ae"]["grown_from"] = old_n
    return config_from_dict(grown, "config + overrides")


class InitialWeights:
    """What `--init MODEL_DIR` starts a stage from: the bundle's config, normalization and the
    weights that stage trains."""

    def __init__(self, path: Path, config: dict[str, Any], mean: Tensor, std: Tensor,
                 weights: dict[str, Tensor]) -> None:
        self.path, self.config, self.mean, self.std, self.weights = path, config, mean, std, weights

    @classmethod
    def read(cls, path: str | Path, stage: str) -> "InitialWeights":
        from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
        from mlct.generate.samplers import sampler_class
        from mlct.io import strip_prefix

        if stage == "ae" and _is_autoencoder_run(Path(path)):
            return cls._from_autoencoder_run(Path(path))
        meta, tensors = read_bundle(path)
        if stage == "ae":
            weights = bundle_autoencoder_state(tensors, path)
        else:
            if sampler_class(meta["sampler"]).stage != stage:
                raise MlctError(f"{path}: a {meta['sampler']} model cannot start `train {stage}`")
            weights = strip_prefix(tensors, "denoiser")
        return cls(Path(path), meta["config"], tensors["norm.mean"], tensors["norm.std"],
                   weights)

    @classmethod
    def _from_autoencoder_run(cls, path: Path) -> "InitialWeights":
        """An autoencoder run (RUN, RUN/ae or a checkpoint): its latest weights, config and
        normalization, so that a later AE stage (latent noise, decoder only) can follow an
        earlier one before any stage 2 exists to export a model from."""
        checkpoint = load_checkpoint(find_autoencoder(path, ae_path=path), with_state=False)
        if "feature_dim" not in checkpoint.meta or checkpoint.meta.get("stage") != "ae":
            raise MlctError(f"{path}: not an autoencoder run or checkpoint")
        norm = checkpoint.module_state("norm")
        return cls(path, checkpoint.meta["config"], norm["mean"], norm["std"],
                   checkpoint.module_state("ae"))

    def load_into(self, stage: Stage) -> None:
        weights = self.weights
        old_n, new_n = int(self.config["ae"]["n_tokens"]), stage.config.ae.n_tokens
        narrow = isinstance(stage, AutoencoderStage) and _narrows_decoder(self.config,
                                                                         stage.config)
        if narrow and new_n != old_n:
            raise MlctError("a decoder of another width (ae.decoder_channels) starts fresh on "
                            "the model's latent: keep ae.n_tokens")
        if isinstance(stage, AutoencoderStage) and _adds_arm_pair(self.config, stage.config):
            from mlct.nn.grow import add_arm_pair  # the new tokens are an arm pair's

            model = stage.model
            weights = add_arm_pair(weights, model.state_dict(), model.body_columns,
                                   model.arm_columns if stage.config.ae.arm_init == "body"
                                   else None)
        elif new_n != old_n:  # a grown latent (nn/grow.py): the autoencoder's or the denoiser's
            from mlct.nn.grow import grow_tokens

            ae = stage.config.ae
            if isinstance(stage, AutoencoderStage) and (ae.temporal or ae.bottleneck):
                # grow_tokens knows the Linear maps' token rows, not a strided conv's or an MLP's
                raise MlctError("a latent grows (ae.n_tokens) with the conv autoencoder's plain "
                                "Linear maps only, not with ae.temporal or ae.bottleneck")

            network = stage.model if isinstance(stage, AutoencoderStage) else stage.denoiser
            weights = grow_tokens(weights, network.state_dict(), old_n, new_n,
                                  stage.config.ae.latent_dim)
        if narrow:
            from mlct.generate.bundle import ENCODER_PREFIXES

            own = stage.model.state_dict()
            if stage.config.ae.decoder_init == "prune":  # the model's decoders, cut narrower
                from mlct.nn.narrow import narrow_decoders

                own = narrow_decoders(weights, own)
            # the encoders' weights load; the decoders (other shapes) are fresh or pruned
            weights = {**own, **{k: v for k, v in weights.items()
                                 if k.startswith(ENCODER_PREFIXES)}}
        try:
            if isinstance(stage, AutoencoderStage):
                stage.model.load_state_dict(weights)
            elif isinstance(stage, (ConsistencyStage, DiffusionStage)):
                stage.start_from(weights)
        except RuntimeError:
            raise MlctError(f"{self.path}: its weights do not fit this stage's network (were "
                            f"the architecture keys overridden?)") from None


def _is_autoencoder_run(path: Path) -> bool:
    """A run, its ae/ folder or a checkpoint of it, rather than an exported model folder."""
    return any((p / "checkpoints").is_dir() for p in (path, path / "ae")) or (
        (path / WEIGHTS).is_file() and (path / STATE).is_file())


def prepare_training(model: torch.nn.Module, lr: float, weight_decay: float,
                     device: torch.device, capturable: bool = False) -> torch.optim.AdamW:
    """Make `model` ready to train on `device` and return its AdamW. On the CPU: its dropouts
    swapped for CheapDropout (nn/dropout.py: PCG64's masks, the same rate, a quarter the time)
    and the AdamW fused (one pass over all parameters instead of a dozen small ops per tensor;
    docs/training.md, "Dropout's random numbers on the CPU"). capturable: AdamW's step count on
    the device, which a CUDA graph needs. bench/train_speed.py times the step with it."""
    cpu = device.type == "cpu"
    if cpu:
        use_cheap_dropout(model)
    return torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=weight_decay,
                             capturable=capturable, fused=True if cpu else None)


def _train(stage_name: str, data_dir: Path, run: Path, config: Config, checkpoint: Any,
           info: distributed.DistInfo, ae_path: str | Path | None,
           progress: bool, stop_at: int | None,
           initial: InitialWeights | None = None) -> dict[str, Any]:
    tc: TrainConfig = getattr(config.train, stage_name)
    stage_dir = run / stage_name
    torch.manual_seed(tc.seed * 1000 + info.rank)  # noise and dropout; data has its own seeds

    dc = config.data
    # The normalization the networks were trained with: a model's under --init; for the latent
    # stages, the autoencoder's (its latents are only defined for the motions it was fed).
    stats = (initial.mean, initial.std) if initial is not None else None
    if stage_name != "ae":
        ae_checkpoint = find_autoencoder(run, ae_path)
        stats = _autoencoder_stats(ae_checkpoint)
        width = DatasetLayout.existing(data_dir).skeleton(None).feature_dim
        if stats[0].shape[0] != width:
            raise MlctError(f"the autoencoder {ae_checkpoint} reads {stats[0].shape[0]}-d motion, "
                            f"the data has {width}-d features")
    mean, std = (None, None) if stats is None else (stats[0].numpy(), stats[1].numpy())
    data = Text2MotionDataset(data_dir, "train", max_motion_length=dc.max_motion_length,
                              unit_length=dc.unit_length, on_bad_file=dc.on_bad_file, seed=tc.seed,
                              mean=mean, std=std)
    val = None
    if (data.layout.root / "val.txt").is_file():
        try:
            val = Text2MotionDataset(data_dir, "val", mean=data.mean, std=data.std,
                                     max_motion_length=dc.max_motion_length,
                                     unit_length=dc.unit_length, on_bad_file=dc.on_bad_file,
                                     seed=tc.seed)
        except MlctError:
            val = None  # an empty val split: no validation, training goes on
    stage = _build_stage(stage_name, config, run, data, val, info, ae_path)
    if stage_name == "ae" and checkpoint is not None:
        if checkpoint.meta.get("feature_dim") != data.skeleton.feature_dim:
            raise MlctError(f"{checkpoint.path} was trained on "
                            f"{checkpoint.meta.get('feature_dim')}-d motion, the data is "
                            f"{data.skeleton.feature_dim}-d")
    if initial is not None and checkpoint is None:
        initial.load_into(stage)
    config = stage.config
    model = stage.trainable
    precision = autocast_precision(tc.precision, stage_name, info.device)
    graphed = tc.cuda_graph and info.device.type == "cuda"
    if tc.cuda_graph:
        _check_capturable(config, stage_name, info)
    optimizer = prepare_training(model, tc.lr, tc.weight_decay, info.device, graphed)
    scheduler = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=tc.max_steps,
                                                           eta_min=tc.lr_min)
    step = 0
    if checkpoint is not None:
        stage.load(checkpoint)
        restore_optimizer(optimizer, checkpoint.state["optimizer"])
        scheduler.load_state_dict(checkpoint.state["scheduler"])
        _set_rng_state(checkpoint.state["rng"][min(info.rank, len(checkpoint.state["rng"]) - 1)],
                       info.device)
        step = int(checkpoint.meta["step"])
    wrapped = DistributedDataParallel(model) if info.enabled else model

    if info.is_main:
        stage_dir.mkdir(parents=True, exist_ok=True)
        write_text(stage_dir / "config.yaml", yaml.safe_dump(config.to_dict(), sort_keys=False))
    log = JsonlLog(stage_dir / "log.jsonl", step if checkpoint is not None else None) \
        if info.is_main else None
    writer = _tensorboard(stage_dir / "tb") if info.is_main else None
    val_batches = fixed_batches(val, tc.batch_size, tc.val_batches) if val is not None else []
    stop = tc.max_steps if stop_at is None else min(stop_at, tc.max_steps)
    loader = step_loader(data, tc.batch_size, tc.seed, step, stop, info.rank, info.world,
                         dc.num_workers, choices_only=tc.cuda_graph)
    captured = None
    if tc.cuda_graph:  # the motions on the device, the step replayed (train/captured_step.py)
        captured = CapturedStep(stage, model, optimizer, ResidentMotions(data, info.device),
                                tc.grad_clip, lambda: _autocast(info.device, precision, False))
    if val_batches and checkpoint is None:  # the starting point, for comparison
        record = {"step": 0, **_validate(stage, val_batches, tc.seed, info.device, precision)}
        if log is not None:
            log.write(record)
            _tb_write(writer, record, 0)

    watch = DivergenceWatch()
    bar = _progress(tc.max_steps, step, progress and info.is_main, f"train {stage_name}")
    last: dict[str, float] = {}
    samples, started = 0, time.perf_counter()
    model.train()
    for batch in loader:
        if captured is None:
            with _autocast(info.device, precision):
                terms = stage.loss(wrapped, batch)
            _finite_loss(terms["loss"], step + 1, stage_dir, info)
            grad_norm = optimizer_update(model, optimizer, terms["loss"], tc.grad_clip)
            stage.after_step()
        else:  # the same update from one graph; the loss is checked after it (nothing saved)
            terms, grad_norm = captured(batch)
            _finite_loss(terms["loss"], step + 1, stage_dir, info)
        scheduler.step()
        step += 1
        samples += len(batch["caption"]) * info.world
        bar.update(1)

        if step % tc.log_every == 0 or step == tc.max_steps:
            last = {k: float(distributed.mean_over_ranks(v.detach().float(), info))
                    for k, v in terms.items()}
            elapsed = time.perf_counter() - started
            record = {"step": step, **last, "grad_norm": float(grad_norm),
                      "lr": scheduler.get_last_lr()[0], "samples_per_s": samples / elapsed,
                      "time": round(time.time(), 3)}  # wall clock: lines up with a GPU monitor
            bar.set_postfix(loss=f"{last['loss']:.4g}")
            if log is not None:
                log.write(record)
                _tb_write(writer, record, step)
            _watch_divergence(watch, record, stage_name, precision, tc.stop_on_divergence,
                              stage_dir, log, info)
        if val_batches and (step % tc.val_every == 0 or step == tc.max_steps):
            record = {"step": step, **_validate(stage, val_batches, tc.seed, info.device,
                                                precision)}
            if log is not None:
                log.write(record)
                _tb_write(writer, record, step)
        if step % tc.ckpt_every == 0 or step in (tc.max_steps, stop):
            rng = _gather_rng(info)
            if info.is_main:
                state = {"optimizer": optimizer.state_dict(), "scheduler": scheduler.state_dict(),
                         "rng": rng}
                save_checkpoint(stage_dir / "checkpoints", step, stage.tensors(), stage.meta(),
                                state)
            distributed.barrier(info)
    bar.close()
    if writer is not None:
        writer.close()
    elapsed = time.perf_counter() - started
    return {"stage": stage_name, "step": step, "last": last, "seconds": elapsed,
            "weights_digest": _digest(model), "is_main": info.is_main,
            "samples_per_s": samples / elapsed if elapsed > 0 else 0.0,
            "checkpoint": str(latest_checkpoint(stage_dir / "checkpoints"))}


def _digest(model: torch.nn.Module) -> str:
    """SHA-256 of the trained weights: DDP ranks must end with the same one."""
    sha = hashlib.sha256()
    for name, tensor in sorted(model.state_dict().items()):
        sha.update(name.encode())
        sha.update(tensor.detach().to("cpu").contiguous().numpy().tobytes())
    return sha.hexdigest()


def _gather_rng(info: distributed.DistInfo) -> list[dict[str, Any]]:
    """Every rank's RNG state, in rank order (rank 0 saves them all)."""
    mine = _rng_state(info.device)
    if not info.enabled:
        return [mine]
    gathered: list[Any] = [None] * info.world
    torch.distributed.all_gather_object(gathered, mine)
    return gathered


def _tensorboard(path: Path) -> Any:
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:  # tensorboard is a dependency, but a broken install should not stop us
        return None
    return SummaryWriter(str(path))


def _tb_write(writer: Any, record: dict[str, Any], step: int) -> None:
    if writer is None:
        return
    for key, value in record.items():
        if key not in ("step", "time") and isinstance(value, (int, float)):
            writer.add_scalar(key, value, step)
