"""Controlled generation: a path walked by the text's own motion, re-timed to the path's pace;
other controls by the best of a few sampled motions; every control then made exact in motion
space by a last, small correction.

The method, chosen by measurement (bench/control.py, docs/control.md), without training:
1. a path (ControlMethod.pace, the default): the text's motion, made as plain generation makes
   it, as long as it must be to cover the path at its own pace, then re-timed so that its root
   is as far along the path as the path asks at every frame, and laid along the path's curve
   (pace.py). The legs' own strides carry the body: a path asking for twice the text's speed
   gets twice its steps per second, not a body sliding over planted feet. A text whose motion
   does not travel (a wave) is met as the other controls are;
2. candidates: `ControlMethod.candidates` motions for the text are sampled in one batch (the
   seed's own motion first) and the one whose decoded joints are nearest the controls is kept.
   A consistency model samples in a few steps, so a batch of 4 costs well under 4 times one,
   and every candidate is a motion the model makes: feet plant, arms swing, the text is done;
3. guidance (optional, off by default; needs PyTorch and the torch backend): inside each
   sampling step, gradient steps on the clean estimate x0 through the decoder (differentiable)
   and the joints, down the control error; the next step re-noises the moved x0. It pulls the
   motion towards far controls, but not far enough for a path at another speed (one latent
   holds about as many strides whatever length it is decoded at: a walk asked for twice its
   speed stayed 0.8 m from the path on average even after 60 gradient steps on the last x0),
   and costs 2.5-3.7x plain generation (docs/control.md);
4. the correction (control/fit.py): root path, heading and the keyframes' root places by one
   smooth low-frequency shift; keyframes by eased per-joint offsets with bone lengths restored
   (FABRIK for single joints); feet that stood in the model's motion held in stance (two-bone
   IK); body-part edits by copying the kept joints and re-attaching the edited bones; a motion
   on a path alone raised onto the floor and its standing feet planted. After the pace it moves
   the root by millimetres on average (bench/control.py --speeds).

The control's world: the result starts where the prefix or edited motion does, or a full pose
at frame 0, or the path's frame-0 waypoint (facing its heading when given); the network makes
the motion facing +Z at the origin, so the targets are moved into that frame, and the result
back out.
"""

from __future__ import annotations

import copy
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from mlct.errors import MlctError, require_torch
from mlct.generate.control import pace
from mlct.generate.control.fit import (REACH_SECONDS, fit_heading, fit_keyframes, fit_path,
                                       lock_feet, on_floor, reattach, turn_y)
from mlct.generate.control.schema import Control
from mlct.generate.output.generated import GeneratedMotion, Generation

if TYPE_CHECKING:  # torch is imported where a control is met by sampling (a light install
    import torch  # walks a path without it: pace.py is numpy)
    from torch import Tensor

# compose.generator.MotionGenerator, which calls generate_with_control: named, not imported (a cycle)
MotionGenerator = Any


@dataclass(frozen=True)
class ControlMethod:
    """How controls are met: a path by the text's own motion re-timed to it (pace), the rest by
    candidates (best of N, one batch), guidance, projection. The default is the one
    bench/control.py picked (docs/control.md)."""

    pace: bool = True  # a path walked by the text's motion, made as long as it needs, re-timed
    guide: bool = False  # decoder guidance inside the sampling steps (PyTorch, torch backend)
    project: bool = True  # the motion-space correction that makes the controls exact
    candidates: int = 4  # motions sampled in one batch; the one nearest the controls is kept
    # guidance: gradient steps on x0 per sampling step, and on the last step's x0 (not
    # re-noised). 2 and 4 since the decoder trained with latent noise 0.2: with 1 and 2 guidance
    # kept 0.93 of plain sampling's waypoint error on tests/test_control.py's walk, with 2 and 4
    # 0.46 (the model before: 0.64 and 0.43; docs/control.md). 4 and 8 since version 7's
    # narrower body decoder, under which 2 and 4 did nothing: over 30 seeds (bench/
    # control.py --guidance) 1.01 of the error at 2 and 4, 0.55 at 4 and 8; version 6
    # 0.73 and 0.55.
    iterations: int = 4
    final_iterations: int = 8
    step: float = 0.9  # guidance: a Gauss-Newton-like step, a fraction of the way to zero error
    reach_seconds: float = REACH_SECONDS
    lock_feet: bool = True  # feet that stood in the model's motion stand after the correction


DEFAULT_METHOD = ControlMethod()


@dataclass(frozen=True)
class Anchor:
    """Where the network's frame (origin, facing +Z) sits in the control's world."""

    origin: np.ndarray  # (3,) with y = 0
    angle: float  # radians about +y

    def to_world(self, points: np.ndarray) -> np.ndarray:
        return turn_y(points, self.angle) + self.origin

    def to_model(self, points: np.ndarray) -> np.ndarray:
        return turn_y(points - self.origin, -self.angle)


def anchor_of(control: Control, skeleton: Any) -> Anchor:
    """The frame the motion starts in: see the module docstring."""
    from mlct.generate.control.facing import heading

    start = control.prefix if control.prefix is not None else control.edit
    pose = None if start is None else start[0]
    if pose is None:
        full = [k for k in control.keyframes if k.frame == 0
                and len(k.joints) == skeleton.n_joints]
        if full:
            pose = np.array([full[0].joints[j] for j in range(skeleton.n_joints)])
    if pose is not None:
        return Anchor(pose[0] * np.array([1.0, 0.0, 1.0]), float(heading(pose, skeleton)))
    if control.path is not None and control.path_frames is not None \
            and 0 in control.path_frames.tolist():
        k = control.path_frames.tolist().index(0)
        angle = 0.0
        if control.heading is not None and np.isfinite(control.heading[k]):
            angle = float(control.heading[k])
        x, z = control.path[k]
        return Anchor(np.array([x, 0.0, z]), angle)
    return Anchor(np.zeros(3), 0.0)


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


def keyframe_list(control: Control, anchor: Anchor) -> list[tuple[int, dict[int, np.ndarray]]]:
    """Every keyframe, the prefix's frames among them, in the network's frame."""
    keys = [(k.frame, {j: anchor.to_model(np.asarray(p, dtype=np.float64))
                       for j, p in k.joints.items()}) for k in control.keyframes]
    if control.prefix is not None:
        local = anchor.to_model(control.prefix)
        keys += [(f, dict(enumerate(local[f]))) for f in range(len(local))]
    return keys


def targets_of(control: Control, anchor: Anchor, skeleton: Any) -> Targets:
    import torch

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
        import torch

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
    import torch

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
    import torch

    from mlct.motion.features import recover_from_ric

    lengths = torch.full((len(z),), frames)
    feats = decoder.decode(z / pipe.config.schedule.latent_scale, lengths, frames)
    return recover_from_ric(feats.float() * pipe.std + pipe.mean)


def candidate_seeds(seed: int, count: int) -> list[int]:
    """The noises a best-of-`count` draws: the seed's own first (count 1 is plain sampling)."""
    return [(int(seed) + k * CANDIDATE_STRIDE) % (2**63) for k in range(count)]


CANDIDATE_STRIDE = 1_000_003  # far apart from the seeds a batch's neighbours use (seed + i)


def guided_latent(pipe: MotionGenerator, text: str, frames: int, seed: int, nfe: int | None,
                  targets: Targets, method: ControlMethod) -> Tensor:
    """(1, n, d): the best of method.candidates latents for the control, each sampled with the
    control's gradient applied to every step's x0 when method.guide."""
    import torch

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


def project(joints: np.ndarray, control: Control, anchor: Anchor, skeleton: Any,
            method: ControlMethod, stood: np.ndarray | None = None) -> np.ndarray:
    """The motion (network frame) corrected to meet every control exactly; the feet that stood
    in `stood` (any frame: a re-timed source before it was laid along a path), else in the
    motion itself, held where they stand."""
    out = joints.astype(np.float64)
    keys = keyframe_list(control, anchor)
    # The root's xz of the path and of the keyframes that pin the root: one smooth correction
    # of the whole track (feet then held in stance), so that a keyframe's local blend only has
    # the pose itself to change, not the body's place on the floor (which skated the feet).
    track = {int(f): pose[0][[0, 2]] for f, pose in keys if 0 in pose}
    if control.path is not None:
        xyz = np.stack([control.path[:, 0], np.zeros(len(control.path)), control.path[:, 1]], 1)
        track.update(zip(control.path_frames.tolist(), anchor.to_model(xyz)[:, [0, 2]]))
    if track:
        frames = np.array(sorted(track))
        out = fit_path(out, frames, np.stack([track[f] for f in frames]))
        if control.heading is not None:
            free = np.isfinite(control.heading)
            out = fit_heading(out, control.path_frames[free],
                              control.heading[free] - anchor.angle, skeleton)
    if keys:
        reach = max(1, int(round(method.reach_seconds * skeleton.fps)))
        out = fit_keyframes(out, keys, skeleton, reach)
    if method.lock_feet and (track or keys):
        keyed: dict[int, set[int]] = {}
        for f, pose in keys:
            keyed.setdefault(int(f), set()).update(pose)
        out = lock_feet(out, joints if stood is None else stood, skeleton, keyed)
    if control.edit is not None:
        out = reattach(out, anchor.to_model(control.edit), control.parts, skeleton)
    return out


def paced(pipe: MotionGenerator, text: str, frames: int, control: Control, nfe: int | None,
          seed: int) -> pace.Laid | None:
    """The text's motion as plain generation makes it, long enough to cover the control's path
    at its own pace, laid along the path (pace.py; in the control's world); None when the text's
    motion does not travel (pace.travels) or a prefix or an edit fixes the frames' timing."""
    if control.path is None or control.prefix is not None or control.edit is not None \
            or frames < 2:
        return None
    fps = pipe.skeleton.fps
    targets = pace.path_targets(control.path, control.path_frames, frames)
    length = float(pace.arc_length(targets)[-1])

    def made(count: int, candidates: int | None = None) -> np.ndarray:  # as plain makes it
        try:
            motion = pipe.generate(text, lengths=count, nfe=nfe, seed=seed,
                                   candidates=candidates)[0]
        except MlctError:  # past the window only a gait keeps going: as long as it may be
            motion = pipe.generate(text, lengths=min(count, pipe.max_frames), nfe=nfe,
                                   seed=seed, candidates=candidates)[0]
        return motion.joints.astype(np.float64)

    # the text's pace from one sample (a third of plain generation's time), then its motion
    # as plain generation makes it (the critic's best candidate) as long as that pace needs
    probe = pace.track_of(made(frames, candidates=1), fps)
    if not pace.travels(probe, length):
        return None
    sources = [made(pace.frames_to_cover(probe, frames, length))]
    tracks = [pace.track_of(sources[0], fps)]
    for _ in range(pace.REMAKES):  # the distance a length covers is not quite proportional
        if pace.covers(tracks[-1], length):
            break
        sources.append(made(pace.frames_to_cover(tracks[-1], len(sources[-1]), length)))
        tracks.append(pace.track_of(sources[-1], fps))
    return pace.lay_along(sources[pace.best_cover(tracks, length)], targets, fps)


@dataclass(frozen=True)
class ControlledMotion:
    """A controlled motion, and its joints before the last correction (world, (T, J, 3)): how
    near the method came by itself (bench/control.py)."""

    motion: GeneratedMotion
    before: np.ndarray


def controlled_motion(pipe: MotionGenerator, text: str, frames: int, control: Control,
                      nfe: int | None, seed: int,
                      method: ControlMethod = DEFAULT_METHOD) -> ControlledMotion:
    """One motion of `frames` frames for `text` that meets `control`, and the same before the
    correction."""
    skeleton = pipe.skeleton
    if skeleton.n_joints != 22:
        raise MlctError("controls need the 22-joint HumanML3D skeleton")
    control = control.check(frames, skeleton)
    if method.guide:
        guidance_decoder(pipe)  # refused before any sampling where it cannot run
    anchor = anchor_of(control, skeleton)
    laid = paced(pipe, text, frames, control, nfe, seed) if method.pace else None
    stood = None  # the motion whose standing feet the correction holds: the one it corrects
    if laid is not None:
        joints, feats, stood = anchor.to_model(laid.joints), None, laid.retimed
    else:  # sampled: candidates and guidance run the networks through torch
        require_torch("this control (keyframes, an edit, a prefix, or a path for a text that "
                      "does not travel)")
        from mlct.motion.joints import features_to_joints

        targets = targets_of(control, anchor, skeleton)
        z = guided_latent(pipe, text, frames, seed, nfe, targets, method)
        feats = pipe.decode(z, [frames])[0]
        joints = features_to_joints(feats).astype(np.float64)
    before = anchor.to_world(joints)
    if method.project:
        joints = project(joints, control, anchor, skeleton, method, stood)
    joints = anchor.to_world(joints)
    if control.edit is not None and method.project:  # exactly the given joints, not rounded
        kept = [j for j in range(skeleton.n_joints) if j not in control.parts]
        joints[:, kept] = control.edit[:, kept]
    path_alone = (control.path is not None and not control.keyframes and control.edit is None
                  and control.prefix is None)
    if path_alone and method.project:
        joints = on_floor(joints)
    features = feats if frames < 2 else None  # derived from the joints when read (generated.py)
    motion = GeneratedMotion(text, features, joints.astype(np.float32), skeleton.fps,
                             skeleton.name, seed)
    if path_alone:
        # a path moves only the pelvis: the feet are planted as a plain motion's are; keyframes,
        # an edit or a prefix pin joints that planting would move, and are left as made
        motion = pipe.planted(motion)
    return ControlledMotion(motion, before)


def generate_controlled(pipe: MotionGenerator, text: str, frames: int, control: Control,
                        nfe: int | None, seed: int,
                        method: ControlMethod = DEFAULT_METHOD) -> GeneratedMotion:
    """One motion of `frames` frames for `text` that meets `control`."""
    return controlled_motion(pipe, text, frames, control, nfe, seed, method).motion


def generate_with_control(pipe: MotionGenerator, texts: list[str], lengths: Any, seconds: Any,
                          nfe: int | None, seed: Any, control: Any) -> Generation:
    """MotionGenerator.generate's path for a control: one text, its length checked."""
    from mlct.generate.control.schema import control_from_dict
    from mlct.generate.seeds import item_seeds

    if len(texts) != 1:
        raise MlctError(f"a control goes with one text, got {len(texts)}")
    if isinstance(control, dict):
        frames = None
        if lengths is not None or seconds is not None:
            frames = pipe._lengths(1, lengths, seconds)[0]
        control = control_from_dict(control, pipe.skeleton, "control", frames)
    if not isinstance(control, Control):
        raise MlctError(f"control must be a Control or a dict, not {type(control).__name__}")
    if lengths is None and seconds is None and control.natural_length() is not None:
        lengths = control.natural_length()
    frames = pipe._lengths(1, lengths, seconds)[0]
    pipe.check_nfe(nfe)
    seeds = item_seeds(1, seed)
    return Generation([generate_controlled(pipe, texts[0], frames, control, nfe, seeds[0])])
