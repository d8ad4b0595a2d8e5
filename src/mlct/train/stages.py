"""The three trainable stages: what each builds, its loss on a batch, what it saves.

- `ae`: the motion autoencoder (Sec. 4.1, Eq. 9).
- `cm`: the denoiser by guided consistency training on frozen AE latents (Algorithm 1).
- `diffusion`: the same denoiser as a noise-predicting latent diffusion model (the baseline).
The loop (train/loop.py) is the same for all three.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, Callable

import torch
import torch.nn.functional as F
from torch import Tensor, nn
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from mlct.config import Config, config_from_dict
from mlct.diffusion.losses import consistency_training_loss, diffusion_training_loss
from mlct.diffusion.parameterization import ConsistencyFunction
from mlct.diffusion.schedule import VPSchedule
from mlct.errors import MlctError
from mlct.generate.samplers import ConsistencySampler
from mlct.nn.build import AnyAutoencoder, build_autoencoder, build_denoiser, latent_clamp
from mlct.motion.features import recover_from_ric, recover_root_rot_pos, root_half_angles
from mlct.nn.masks import lengths_to_mask
from mlct.io import prefixed
from mlct.train.checkpoint import Checkpoint, latest_checkpoint, load_checkpoint

# the conv autoencoder's arm-pair decoder (ae.freeze_arm_decoder)
ARM_DECODER_PREFIXES = ("arm_from_tokens.", "arm_decoder.")


def schedule_of(config: Config) -> VPSchedule:
    return VPSchedule(beta_min=config.schedule.beta_min, beta_max=config.schedule.beta_max)


def longest(batch: dict[str, Any], lengths: Tensor) -> int:
    """The frames a batch is cut to: its longest item's. A fixed-shape batch (train/
    captured_step.py: "static") keeps its whole padded width, since a CUDA graph cannot read the
    lengths; masks make the two the same computation."""
    return batch["motion"].shape[1] if batch.get("static") else int(lengths.max())


def _masked_smooth_l1(a: Tensor, b: Tensor, mask: Tensor, beta: float = 1.0) -> Tensor:
    """Smooth-L1 averaged over the valid frames only. a, b (B, T, ...), mask (B, T)."""
    per = F.smooth_l1_loss(a, b, reduction="none", beta=beta).flatten(2).mean(2)  # (B, T)
    return (per * mask).sum() / mask.sum().clamp(min=1)


def _root_trajectory(features: Tensor) -> Tensor:
    """(B, T, D) real-unit features -> (B, T, 3): the root's heading (the running sum of its
    angular velocities, radians) and its x, z on the ground (metres), as recover_root_rot_pos
    integrates them: the quantities a turn's angle and a walk's distance are read from."""
    _, position = recover_root_rot_pos(features)
    # twice the yaw half-angle, negated: the read-outs' heading (to the person's left positive)
    heading = -2.0 * root_half_angles(features)
    return torch.cat([heading[..., None], position[..., 0::2]], dim=-1)


class Normalizer(nn.Module):
    """Dataset Mean/Std as buffers: they travel with the checkpoint and the model bundle."""

    def __init__(self, mean: Tensor, std: Tensor) -> None:
        super().__init__()
        self.register_buffer("mean", mean.float().clone())
        self.register_buffer("std", std.float().clone())

    def denormalize(self, x: Tensor) -> Tensor:
        return x * self.std.to(x) + self.mean.to(x)


class Stage:
    """Base: a trainable module, a loss, the tensors and metadata a checkpoint holds."""

    name = ""

    def __init__(self, config: Config, device: torch.device) -> None:
        self.config = config
        self.device = device

    @property
    def trainable(self) -> nn.Module:  # the module the optimizer trains and DDP wraps
        raise NotImplementedError

    def loss(self, model: nn.Module, batch: dict[str, Any],
             generator: torch.Generator | None = None) -> dict[str, Tensor]:
        raise NotImplementedError

    def after_step(self) -> None:
        """Called after each optimizer step (EMA updates)."""

    def after_step_in_graph(self) -> None:
        """after_step as a CUDA graph can hold it (train/captured_step.py), once after_step ran."""
        self.after_step()

    def tensors(self) -> dict[str, Tensor]:
        raise NotImplementedError

    def meta(self) -> dict[str, Any]:
        raise NotImplementedError

    def load(self, checkpoint: Checkpoint) -> None:
        raise NotImplementedError

    def train(self, mode: bool = True) -> None:
        self.trainable.train(mode)


class AutoencoderStage(Stage):
    name = "ae"

    def __init__(self, config: Config, device: torch.device, mean: Tensor, std: Tensor,
                 skeleton: str) -> None:
        super().__init__(config, device)
        self.skeleton = skeleton
        self.feature_dim = int(mean.shape[0])
        self.model = build_autoencoder(config, self.feature_dim).to(device)
        self.norm = Normalizer(mean, std).to(device)
        if config.ae.freeze_encoder:  # its gradients are never computed: AdamW skips them
            from mlct.generate.bundle import ENCODER_PREFIXES

            # an arm pair added to a model (nn/grow.py add_arm_pair) is new: its encoder trains
            added = (("arm_encoder.", "arm_to_tokens.")
                     if config.ae.grown_from and config.ae.arm_tokens else ())
            for name, parameter in self.model.named_parameters():
                if name.startswith(ENCODER_PREFIXES) and not (added and name.startswith(added)):
                    parameter.requires_grad_(False)
            if config.ae.grown_from and not added:
                self._train_new_token_rows(config.ae.grown_from)
        if config.ae.freeze_arm_decoder:
            if not config.ae.arm_tokens:
                raise MlctError("ae.freeze_arm_decoder needs an arm pair (ae.arm_tokens > 0)")
            for name, parameter in self.model.named_parameters():
                if name.startswith(ARM_DECODER_PREFIXES):
                    parameter.requires_grad_(False)

    def _train_new_token_rows(self, old_n: int) -> None:
        """A grown latent (nn/grow.py) under a frozen encoder: the new tokens' encoder rows
        train, the old tokens' get no gradient (so AdamW, without weight decay, never moves
        them) and keep their latents' meaning for the stage 2 trained on them."""
        from mlct.nn.grow import old_token_rows

        if self.config.train.ae.weight_decay:
            raise MlctError("ae.grown_from with ae.freeze_encoder needs train.ae.weight_decay=0: "
                            "weight decay would move the old tokens' frozen rows")
        a = self.config.ae
        for parameter in self.model.to_tokens.parameters():
            keep = old_token_rows(parameter.shape[0], old_n, a.n_tokens, a.latent_dim)
            keep = keep.to(parameter.device).view(-1, *[1] * (parameter.ndim - 1))
            parameter.requires_grad_(True)
            parameter.register_hook(lambda grad, keep=keep: grad.masked_fill(keep, 0.0))

    @property
    def trainable(self) -> nn.Module:
        return self.model

    def loss(self, model: nn.Module, batch: dict[str, Any],
             generator: torch.Generator | None = None) -> dict[str, Tensor]:
        x = batch["motion"].to(self.device)  # (B, L, D) normalized, zero-padded
        lengths = batch["length"].to(self.device)
        frames = longest(batch, lengths)
        x = x[:, :frames]
        noise = self.config.ae.latent_noise if model.training else 0.0
        if self.config.ae.hold_extension > 0:  # some items decoded past their end
            static = bool(batch.get("static"))
            longer = self._extended_lengths(lengths, generator, on_device=static)
            # a fixed-shape batch keeps its whole padded width, which no extension passes
            width = frames if static else int(longer.max())
            recon, latent = model(x, lengths, longer, noise, decode_frames=width)  # (B, width, D)
            x, lengths = self._held_target(x, lengths, longer, width), longer
            frames = width
        else:
            recon, latent = model(x, lengths, None, noise)  # (B, frames, D)
        mask = lengths_to_mask(lengths, frames).to(x.dtype)  # (B, frames)
        feature = _masked_smooth_l1(recon, x, mask)  # Eq. 9, first term
        # Eq. 9, second term: joint positions through recover_from_ric, on real units.
        real_hat, real = self.norm.denormalize(recon).float(), self.norm.denormalize(x).float()
        joints_hat, joints = recover_from_ric(real_hat), recover_from_ric(real)
        joint = _masked_smooth_l1(joints_hat, joints, mask, self.config.ae.joint_beta)
        total = feature + self.config.ae.joint_weight * joint
        out = {"feature": feature.detach(), "joint": joint.detach()}
        if self.config.ae.velocity_weight > 0 and frames > 1:
            # Ours: frame-to-frame differences, so that a sharp event (a jump's take-off, a
            # foot's lift) costs as much as its size and cannot be smoothed into the mean.
            pairs = mask[:, 1:] * mask[:, :-1]
            velocity = _masked_smooth_l1(recon.diff(dim=1), x.diff(dim=1), pairs)
            total = total + self.config.ae.velocity_weight * velocity
            out["velocity"] = velocity.detach()
        if self.config.ae.trajectory_weight > 0:
            trajectory = _masked_smooth_l1(_root_trajectory(real_hat), _root_trajectory(real), mask)
            total = total + self.config.ae.trajectory_weight * trajectory
            out["trajectory"] = trajectory.detach()
        if latent.kl is not None:
            total = total + self.config.ae.kl_weight * latent.kl
            out["kl"] = latent.kl.detach()
        out["loss"] = total
        return out

    def _extended_lengths(self, lengths: Tensor, generator: torch.Generator | None,
                          on_device: bool = False) -> Tensor:
        """A hold_extension share of the items, lengthened by a random number of frames (up
        to the horizon); the others as they are. Drawn on the host (the generator's device
        where one is given), or on_device, as a CUDA graph needs."""
        where = lengths.device if on_device else (
            generator.device if generator is not None else torch.device("cpu"))
        draw = lambda: torch.rand(len(lengths), generator=generator,  # noqa: E731
                                  device=where).to(lengths.device)
        chosen = draw() < self.config.ae.hold_extension
        room = (self.config.data.max_motion_length - lengths).clamp(min=0)
        extra = (draw() * (room + 1)).long()
        return lengths + torch.where(chosen, extra, torch.zeros_like(extra))

    def _held_target(self, x: Tensor, lengths: Tensor, longer: Tensor, frames: int) -> Tensor:
        """x (B, T, D) extended to `frames` (>= max(longer)): past each clip's end, its last
        pose held still (velocities 0, feet on the ground) up to `longer`, zeros after."""
        held = self._held_pose(x[torch.arange(len(lengths), device=x.device), lengths - 1])
        steps = torch.arange(frames, device=x.device)[None, :]  # (1, frames)
        past = (steps >= lengths[:, None]) & (steps < longer[:, None])  # (B, frames)
        target = torch.zeros(len(lengths), frames, x.shape[-1], device=x.device, dtype=x.dtype)
        target[:, : x.shape[1]] = x
        return torch.where(past[..., None], held[:, None, :], target)

    def _held_pose(self, last: Tensor) -> Tensor:
        """(B, D) normalized last frames -> the same poses standing still, normalized."""
        from mlct.motion.features import n_joints_for_dim
        from mlct.motion.skeleton import FeatureLayout

        raw = self.norm.denormalize(last).clone()
        groups = FeatureLayout(n_joints_for_dim(raw.shape[-1])).groups
        for name in ("root_rot_velocity", "root_linear_velocity", "local_velocity"):
            raw[:, groups[name]] = 0.0
        raw[:, groups["foot_contact"]] = 1.0
        return (raw - self.norm.mean) / self.norm.std

    def tensors(self) -> dict[str, Tensor]:
        return {**prefixed("ae", self.model.state_dict()), **prefixed("norm", self.norm.state_dict())}

    def meta(self) -> dict[str, Any]:
        return {"stage": self.name, "config": self.config.to_dict(),
                "feature_dim": self.feature_dim, "skeleton": self.skeleton}

    def load(self, checkpoint: Checkpoint) -> None:
        self.model.load_state_dict(checkpoint.module_state("ae"))
        self.norm.load_state_dict(checkpoint.module_state("norm"))


def update_ema_in_graph(ema: AveragedModel, module: nn.Module) -> None:
    """AveragedModel.update_parameters (use_buffers=True) for an EMA updated once already,
    without its first-call test: bool(n_averaged == 0) reads the device, which a CUDA graph
    cannot. The same multi_avg_fn over the parameters and buffers, grouped by dtype as there."""
    ours = [t.detach() for t in itertools.chain(ema.module.parameters(), ema.module.buffers())]
    theirs = [t.detach() for t in itertools.chain(module.parameters(), module.buffers())]
    groups: dict[torch.dtype, tuple[list[Tensor], list[Tensor]]] = {}
    for mine, source in zip(ours, theirs, strict=True):
        pair = groups.setdefault(mine.dtype, ([], []))
        pair[0].append(mine)
        pair[1].append(source)
    for mine_list, source_list in groups.values():
        ema.multi_avg_fn(mine_list, source_list, ema.n_averaged)
    ema.n_averaged += 1


def find_autoencoder(run: Path, ae_path: str | Path | None) -> Path:
    """The AE checkpoint a stage-2 run builds on: --ae PATH, else RUN/ae's latest.

    PATH may be a checkpoint directory, an AE stage directory (RUN/ae) or a whole run (RUN):
    the latter two resolve to their latest checkpoint."""
    if ae_path is not None:
        path = Path(ae_path)
        for checkpoints in (path / "checkpoints", path / "ae" / "checkpoints"):
            if checkpoints.is_dir() and (found := latest_checkpoint(checkpoints)) is not None:
                return found
        return path
    found = latest_checkpoint(run / "ae" / "checkpoints")
    if found is None:
        raise MlctError(f"{run / 'ae'}: no trained autoencoder; run `mlct train ae` with this "
                        f"--out first, or pass --ae CHECKPOINT")
    return found


def load_frozen_autoencoder(path: Path, device: torch.device
                            ) -> tuple[AnyAutoencoder, Normalizer, dict[str, Any]]:
    """A trained AE in eval mode with its Mean/Std, gradients off, and its checkpoint metadata."""
    checkpoint = load_checkpoint(path, with_state=False)
    if "feature_dim" not in checkpoint.meta or not any(
            key.startswith("ae.encoder.") for key in checkpoint.tensors):
        raise MlctError(f"{path}: not an autoencoder checkpoint")
    ae_config = config_from_dict(checkpoint.meta["config"], str(path))
    model = build_autoencoder(ae_config, checkpoint.meta["feature_dim"])
    model.load_state_dict(checkpoint.module_state("ae"))
    state = checkpoint.module_state("norm")
    norm = Normalizer(state["mean"], state["std"])
    model.to(device).eval().requires_grad_(False)
    return model, norm.to(device), checkpoint.meta


def noisy_text(cond: Tensor, scale: float, generator: torch.Generator | None = None,
               residuals: Tensor | None = None, draws: int = 8) -> Tensor:
    """(B, c) text vectors plus Gaussian noise (consistency.text_noise; unchanged at 0).
    Without `residuals`: isotropic, its expected norm `scale` times each vector's. With
    `residuals` (M, c), how captions of one motion differ from their mean: a random Gaussian
    mix of `draws` of them, whose covariance is theirs, times `scale`."""
    if scale <= 0:
        return cond
    if residuals is None:
        noise = torch.randn(cond.shape, generator=generator, device=cond.device, dtype=cond.dtype)
        return cond + noise * (scale * cond.norm(dim=-1, keepdim=True) / cond.shape[-1] ** 0.5)
    rows = torch.randint(0, residuals.shape[0], (cond.shape[0], draws), generator=generator,
                         device=residuals.device)
    weights = torch.randn((cond.shape[0], draws, 1), generator=generator,
                          device=residuals.device)
    noise = (weights * residuals[rows]).sum(dim=1) / draws ** 0.5  # (B, c)
    return cond + scale * noise.to(cond.dtype)


class TextTable:
    """Frozen text embeddings of every caption a run sees, encoded once (through the disk cache)."""

    def __init__(self, encoder: Any, captions: list[str], device: torch.device) -> None:
        self.name, self.dim = encoder.name, encoder.dim
        unique = sorted(set(captions))
        embeddings = encoder.encode(unique) if unique else torch.zeros(0, encoder.dim)
        self.index = {caption: row for row, caption in enumerate(unique)}
        self.table = embeddings.float().to(device)  # (N, c)
        self.null = encoder.null_embedding().float().to(device)  # (c,) the embedding of ""
        self.residuals: Tensor | None = None  # caption_residuals, for text_noise_shape=captions

    def rows(self, captions: list[str]) -> Tensor:
        """(B,) long, on the host: each caption's row of the table."""
        try:
            return torch.tensor([self.index[c] for c in captions], dtype=torch.long)
        except KeyError as err:
            raise MlctError(f"caption {err} was not embedded at start-up") from None

    def __call__(self, captions: list[str]) -> Tensor:
        return self.table[self.rows(captions).to(self.table.device)]  # (B, c)

    def caption_residuals(self, groups: list[list[str]]) -> Tensor:
        """(M, c): each caption's embedding minus the mean of its group's (the captions of one
        motion), for the groups of two or more; the spread a rephrasing moves a vector by."""
        out = []
        for group in groups:
            rows = sorted({self.index[c] for c in group if c in self.index})
            if len(rows) >= 2:
                vectors = self.table[rows]
                # unbiased: a group of n has n - 1 degrees of freedom around its own mean
                out.append((vectors - vectors.mean(dim=0)) * (len(rows) / (len(rows) - 1)) ** 0.5)
        if not out:
            raise MlctError("consistency.text_noise_shape=captions needs motions with two or "
                            "more captions")
        return torch.cat(out)

    def of_batch(self, batch: dict[str, Any]) -> Tensor:
        """The batch's embeddings: from its rows when it carries them (a fixed-shape batch,
        train/captured_step.py), else looked up by caption."""
        if "text_rows" in batch:
            return self.table[batch["text_rows"]]
        return self(batch["caption"])


class LatentStage(Stage):
    """Shared by cm and diffusion: frozen AE latents, text table, denoiser + its EMA copy."""

    ema_decay = 0.0

    def __init__(self, config: Config, device: torch.device, ae_path: Path, text: TextTable
                 ) -> None:
        self.ae, self.norm, ae_meta = load_frozen_autoencoder(ae_path, device)
        # The AE's own config section is authoritative: the latent shape comes from it.
        merged = config.to_dict()
        merged["ae"] = ae_meta["config"]["ae"]
        merged["data"] = ae_meta["config"]["data"]
        super().__init__(config_from_dict(merged), device)
        self.ae_meta = ae_meta
        self.text = text
        self.schedule = schedule_of(self.config)
        self.denoiser = build_denoiser(self.config, text.dim).to(device)
        self.clamp = latent_clamp(self.config)

    def latents(self, batch: dict[str, Any]) -> Tensor:
        x = batch["motion"].to(self.device)
        lengths = batch["length"].to(self.device)
        with torch.no_grad():
            z = self.ae.encode(x[:, : longest(batch, lengths)], lengths).z.float()  # (B, n, d)
        return z * self.config.schedule.latent_scale  # stage 2's latent space

    def _ema(self, module: nn.Module) -> AveragedModel:
        # its update count on the module's device, where a CUDA graph can count (captured_step)
        ema = AveragedModel(module, device=self.device,
                            multi_avg_fn=get_ema_multi_avg_fn(self.ema_decay), use_buffers=True)
        return ema.eval().requires_grad_(False)

    def _frozen_and_online(self) -> dict[str, Tensor]:
        """The frozen AE, its normalization and the online denoiser, for the checkpoint."""
        return {**prefixed("ae", self.ae.state_dict()), **prefixed("norm", self.norm.state_dict()),
                **prefixed("denoiser", self.denoiser.state_dict())}

    def meta(self) -> dict[str, Any]:
        return {"stage": self.name, "config": self.config.to_dict(),
                "feature_dim": self.ae_meta["feature_dim"], "skeleton": self.ae_meta["skeleton"],
                "text_encoder": self.text.name, "text_dim": self.text.dim}

    def _check_compatible(self, checkpoint: Checkpoint) -> None:
        if checkpoint.meta.get("text_encoder") != self.text.name:
            raise MlctError(f"{checkpoint.path}: trained with text encoder "
                            f"{checkpoint.meta.get('text_encoder')!r}, not {self.text.name!r}")


class ConsistencyStage(LatentStage):
    name = "cm"

    def __init__(self, config: Config, device: torch.device, ae_path: Path, text: TextTable
                 ) -> None:
        super().__init__(config, device, ae_path, text)
        s, c = self.config.schedule, self.config.consistency
        self.ema_decay = c.target_decay
        self.online = ConsistencyFunction(self.denoiser, s.eta, s.time_scale)
        # Target network S_psi: the EMA of the online network (Eq. 15), or the online network
        # itself under stop-gradient (the loss calls it inside no_grad).
        self.target = self._ema(self.online) if c.target == "ema" else None
        # the time grid: Algorithm 1 trains on the one that Algorithm 2 samples from
        self.grid = ConsistencySampler(self.config, device).grid

    @property
    def trainable(self) -> nn.Module:
        return self.online

    def loss(self, model: nn.Module, batch: dict[str, Any],
             generator: torch.Generator | None = None) -> dict[str, Tensor]:
        c = self.config.consistency
        target = self.target.module if self.target is not None else self.online
        return consistency_training_loss(
            model, target, self.latents(batch),
            noisy_text(self.text.of_batch(batch), c.text_noise, generator,
                       self.text.residuals), self.text.null,
            self.schedule, self.grid, guidance=c.guidance, uncond_weight=c.uncond_weight,
            huber_c=c.huber_c, clamp=self.clamp, denoise_weight=c.denoise_weight,
            denoise_max_t=c.denoise_max_t, generator=generator, decode=self._decoder(batch) if c.motion_weight else None,
            motion_weight=c.motion_weight, motion_items=c.motion_items)

    def _decoder(self, batch: dict[str, Any]) -> Callable[[Tensor], Tensor]:
        """Stage 2's latents of the batch's first items -> the frozen decoder's motion features
        (normalized, padding zero) at their lengths: differentiable in the latent, for
        consistency.motion_weight."""
        lengths = batch["length"].to(self.device)
        scale = self.config.schedule.latent_scale

        def decode(z: Tensor) -> Tensor:
            items = lengths[: len(z)]
            return self.ae.decode(z / scale, items, int(items.max()))
        return decode

    def after_step(self) -> None:
        if self.target is not None:
            self.target.update_parameters(self.online)

    def after_step_in_graph(self) -> None:
        if self.target is not None:
            update_ema_in_graph(self.target, self.online)

    def start_from(self, denoiser: dict[str, Tensor]) -> None:
        """Fine-tuning: the denoiser's weights from a model; the EMA target restarts from them."""
        self.denoiser.load_state_dict(denoiser)
        if self.target is not None:
            self.target = self._ema(self.online)

    def sampling_denoiser(self) -> nn.Module:
        """The weights generation uses: the EMA target network, else the online one."""
        return self.target.module.net if self.target is not None else self.denoiser

    def tensors(self) -> dict[str, Tensor]:
        out = self._frozen_and_online()
        if self.target is not None:
            out.update(prefixed("target", self.target.state_dict()))
        return out

    def load(self, checkpoint: Checkpoint) -> None:
        self._check_compatible(checkpoint)
        self.denoiser.load_state_dict(checkpoint.module_state("denoiser"))
        if self.target is not None:
            self.target.load_state_dict(checkpoint.module_state("target"))


class DiffusionStage(LatentStage):
    name = "diffusion"

    def __init__(self, config: Config, device: torch.device, ae_path: Path, text: TextTable
                 ) -> None:
        super().__init__(config, device, ae_path, text)
        self.ema_decay = self.config.diffusion.ema_decay
        self.ema = self._ema(self.denoiser)

    @property
    def trainable(self) -> nn.Module:
        return self.denoiser

    def loss(self, model: nn.Module, batch: dict[str, Any],
             generator: torch.Generator | None = None) -> dict[str, Tensor]:
        return diffusion_training_loss(
            model, self.latents(batch), self.text.of_batch(batch), self.text.null,
            self.schedule, cond_dropout=self.config.diffusion.cond_dropout, generator=generator)

    def after_step(self) -> None:
        self.ema.update_parameters(self.denoiser)

    def after_step_in_graph(self) -> None:
        update_ema_in_graph(self.ema, self.denoiser)

    def start_from(self, denoiser: dict[str, Tensor]) -> None:
        """Fine-tuning: the denoiser's weights from a model; the EMA restarts from them."""
        self.denoiser.load_state_dict(denoiser)
        self.ema = self._ema(self.denoiser)

    def sampling_denoiser(self) -> nn.Module:
        return self.ema.module

    def tensors(self) -> dict[str, Tensor]:
        return {**self._frozen_and_online(), **prefixed("target", self.ema.state_dict())}

    def load(self, checkpoint: Checkpoint) -> None:
        self._check_compatible(checkpoint)
        self.denoiser.load_state_dict(checkpoint.module_state("denoiser"))
        self.ema.load_state_dict(checkpoint.module_state("target"))
