"""Controls met by sampling (controlled.py's candidates and guidance): the controls as
tensors, their loss on decoded joints, the decoder made differentiable, and the latent that is
the best of a few samples, each optionally guided through the decoder inside the consistency
steps. PyTorch: controlled.py imports this module only after require_torch."""

from __future__ import annotations

import copy
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import Tensor

from mlct.errors import MlctError, require_torch
from mlct.generate.control.world import Anchor, keyframe_list
from mlct.generate.control.schema import Control
from mlct.motion.features import recover_from_ric

# compose.generator.MotionGenerator: named, not imported (a cycle)
MotionGenerator = Any


@dataclass
class Targets:
    """A control in the network's frame, as tensors for the guidance loss."""

    path_frames: Tensor | None = None  # (K,)
    path_xz: Tensor | None = None  # (K, 2)
    head_frames: Tensor | None = None
    head: Tensor | None = None  # (H,) radians
    key_frames: Tensor | None = None  # (M,)
    key_joints: Tensor | None = None  # (M,)
    key_pos: Tensor | None = None  # (M, 3)
    kept: Tensor | None = None  # (T, K, 3) an edit's kept joints
    kept_joints: list[int] | None = None


def targets_of(control: Control, anchor: Anchor, skeleton: Any) -> Targets:
    out = Targets()
    if control.path is not None:
        xyz = np.stack([control.path[:, 0], np.zeros(len(control.path)), control.path[:, 1]], 1)
        local = anchor.to_model(xyz)
        out.path_frames = torch.as_tensor(control.path_frames)
        out.path_xz = torch.as_tensor(local[:, [0, 2]], dtype=torch.float32)
        if control.heading is not None:
            free = np.isfinite(control.heading)
            out.head_frames = torch.as_tensor(control.path_frames[free])
            out.head = torch.as_tensor(control.heading[free] - anchor.angle, dtype=torch.float32)
    keys = keyframe_list(control, anchor)
    if keys:
        rows = [(f, j, p) for f, joints in keys for j, p in joints.items()]
        out.key_frames = torch.tensor([r[0] for r in rows])
        out.key_joints = torch.tensor([r[1] for r in rows])
        out.key_pos = torch.tensor(np.stack([r[2] for r in rows]), dtype=torch.float32)
    if control.edit is not None:
        out.kept_joints = [j for j in range(skeleton.n_joints) if j not in control.parts]
        out.kept = torch.as_tensor(anchor.to_model(control.edit)[:, out.kept_joints],
                                   dtype=torch.float32)
    return out


def control_loss(joints: Tensor, t: Targets, skeleton: Any) -> Tensor:
    """Squared control error (m^2; headings as 1 - cos) of joints (T, J, 3): the mean over each
    kind of control, summed over kinds."""
    loss = joints.new_zeros(())
    if t.path_xz is not None:
        loss = loss + ((joints[t.path_frames, 0][:, [0, 2]] - t.path_xz) ** 2).sum(-1).mean()
    if t.head is not None:
        r_hip, l_hip, r_sh, l_sh = skeleton.face_joints
        across = joints[t.head_frames, r_hip] - joints[t.head_frames, l_hip] \
            + joints[t.head_frames, r_sh] - joints[t.head_frames, l_sh]
        angle = torch.atan2(across[:, 2], -across[:, 0])
        loss = loss + (1 - torch.cos(angle - t.head)).mean()
    if t.key_pos is not None:
        loss = loss + ((joints[t.key_frames, t.key_joints] - t.key_pos) ** 2).sum(-1).mean()
    if t.kept is not None:
        loss = loss + ((joints[:, t.kept_joints] - t.kept) ** 2).sum(-1).mean()
    return loss


_DECODERS: "weakref.WeakKeyDictionary[Any, torch.nn.Module]" = weakref.WeakKeyDictionary()


def differentiable_decoder(pipe: MotionGenerator) -> torch.nn.Module | None:
    """The generator's decoder with plain (autograd-aware) products, or None when its backend
    has none (onnx): mlct.nn.inference's prepacked oneDNN products have no backward."""
    if not isinstance(pipe.ae, torch.nn.Module):
        return None
    if pipe not in _DECODERS:
        ae = copy.deepcopy(pipe.ae)
        for module in ae.modules():
            if hasattr(module, "prepack"):
                module.prepack = False
                module._packed = None
        _DECODERS[pipe] = ae
    return _DECODERS[pipe]


def guidance_decoder(pipe: MotionGenerator) -> torch.nn.Module:
    """differentiable_decoder, or a one-line error naming what guidance needs (it would
    otherwise silently do nothing): PyTorch, then the torch backend."""
    require_torch("decoder guidance (ControlMethod(guide=True))")
    decoder = differentiable_decoder(pipe)
    if decoder is None:
        raise MlctError(f"decoder guidance needs a differentiable decoder, which the "
                        f"{getattr(pipe, 'backend', 'onnx')} backend has not; load the model "
                        f"with backend='torch', or use ControlMethod(guide=False)")
    return decoder


def _joints(pipe: MotionGenerator, decoder: Any, z: Tensor, frames: int) -> Tensor:
    """(B, T, J, 3) joints of latents z (B, n, d) through `decoder`."""
    
    lengths = torch.full((len(z),), frames)
    feats = decoder.decode(z / pipe.config.schedule.latent_scale, lengths, frames)
    return recover_from_ric(feats.float() * pipe.std + pipe.mean)


def candidate_seeds(seed: int, count: int) -> list[int]:
    """The noises a best-of-`count` draws: the seed's own first (count 1 is plain sampling)."""
    return [(int(seed) + k * CANDIDATE_STRIDE) % (2**63) for k in range(count)]


CANDIDATE_STRIDE = 1_000_003  # far apart from the seeds a batch's neighbours use (seed + i)


def guided_latent(pipe: MotionGenerator, text: str, frames: int, seed: int, nfe: int | None,
                  targets: Targets, method: Any) -> Tensor:
    """(1, n, d): the best of method.candidates latents for the control, each sampled with the
    control's gradient applied to every step's x0 when method.guide (method: controlled.py's
    ControlMethod, which imports this module)."""
    decoder = guidance_decoder(pipe) if method.guide else None
    count = max(1, method.candidates)
    # as generate()'s (the onnx backend's vectors are arrays: tensors here, for the sampler)
    cond = torch.as_tensor(pipe.sampling_text(pipe.encode_text([text]))).expand(count, -1)
    generators = [torch.Generator().manual_seed(s) for s in candidate_seeds(seed, count)]
    steps = pipe.check_nfe(nfe)
    uncond = torch.as_tensor(pipe.encode_text([""])) if pipe.sampler.cfg else None

    def losses(joints: Tensor) -> Tensor:  # (B,) one control loss per candidate
        return torch.stack([control_loss(j, targets, pipe.skeleton) for j in joints])

    calls = [0]

    def guide(x0: Tensor) -> Tensor:
        calls[0] += 1
        last = calls[0] == steps
        with torch.enable_grad():
            z = x0.detach().clone()
            for _ in range(method.final_iterations if last else method.iterations):
                z.requires_grad_(True)
                loss = losses(_joints(pipe, decoder, z, frames))  # (B,)
                (grad,) = torch.autograd.grad(loss.sum(), z)
                # A Gauss-Newton step along the gradient: for a loss ~ |e|^2, the step that
                # would remove `step` of it if the decoder were linear along this direction.
                norm2 = (grad ** 2).sum(dim=(1, 2), keepdim=True).clamp_min(1e-12)
                z = (z - method.step * loss.detach()[:, None, None] / norm2 * grad).detach()
        return z

    x = pipe.sampler.noise((count, *pipe.ae.latent_shape), generators)
    with torch.no_grad():
        z = pipe.sampler.sample(pipe.denoiser, x, cond, steps, generator=generators,
                                uncond=uncond, guide=guide if method.guide else None)
        if count == 1:
            return z
        best = int(torch.argmin(losses(_joints(pipe, pipe.ae, z, frames))))
    return z[best:best + 1]
