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
3. guidance (optional, off by default; needs PyTorch and the torch backend; sampled.py holds
   it and the candidates, and is imported only where a control is met by sampling): inside each
   sampling step, gradient steps on the clean estimate x0 through the decoder (differentiable)
   and the joints, down the control error; the next step re-noises the moved x0. It pulls the
   motion towards far controls, but not far enough for a path at another speed (one latent
   holds about as many strides whatever length it is decoded at: a walk asked for twice its
   speed stayed 0.8 m from the path on average even after 60 gradient steps on the last x0),
   and costs 2.5-3.7x plain generation (docs/control.md);
4. steering (optional, off by default; PyTorch, steered.py): the last consistency steps' x0
   moved by what the autoencoder's encoder makes of the decoded motion fitted to the controls
   (a path re-timed and laid along it, pace.py, then the correction's fits). The encoder gives
   back a motion re-timed to another pace as one that hardly moves, so it leaves decimetres to
   metres before the correction (docs/control.md);
5. the correction (control/fit.py): root path, heading and the keyframes' root places by one
   smooth low-frequency shift; keyframes by eased per-joint offsets with bone lengths restored
   (FABRIK for single joints); feet that stood in the model's motion held in stance (two-bone
   IK); body-part edits by copying the kept joints and re-attaching the edited bones; a motion
   on a path alone raised onto the floor and its standing feet planted. After the pace it moves
   the root by millimetres on average (bench/control.py --speeds).

The control's world (where the result starts and faces): world.py.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from mlct.errors import MlctError, require_torch
from mlct.generate.control import pace
from mlct.generate.control.pace import Pacing
from mlct.generate.control.fit import (REACH_SECONDS, fit_heading, fit_keyframes, fit_path,
                                       lock_feet, on_floor, reattach)
from mlct.generate.control.schema import Control
from mlct.generate.control.world import Anchor, anchor_of, keyframe_list
from mlct.generate.output.generated import GeneratedMotion, Generation

# compose.generator.MotionGenerator, which calls generate_with_control: named, not imported
MotionGenerator = Any


@dataclass(frozen=True)
class ControlMethod:
    """How controls are met: a path by the text's own motion re-timed to it (pace), the rest by
    candidates (best of N, one batch), guidance or steering inside the sampling steps, then the
    correction (project). The default is the one bench/control.py picked (docs/control.md)."""

    pace: bool = True  # a path walked by the text's motion, made as long as it needs, re-timed
    pacing: Pacing = Pacing()  # how the pace makes its source and re-times it
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
    # steering (steered.py; PyTorch), in place of the pace and the candidates: the last
    # `steered_steps` consistency steps' x0 moved by the encoder's image of the decoded motion
    # fitted to the controls. 2 of 5: on a walk and a jog at their own pace (3 seeds) 31 / 187
    # cm from the path before the correction at 2, 35 / 151 at 1, 98 / 182 at 3, 124 / 268 at 5
    steer: bool = False
    steered_steps: int = 2


DEFAULT_METHOD = ControlMethod()


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
          seed: int, pacing: Pacing = Pacing()) -> pace.Laid | None:
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
        if pace.covers(tracks[-1], length, pacing.covers):
            break
        sources.append(made(pace.frames_to_cover(tracks[-1], len(sources[-1]), length)))
        tracks.append(pace.track_of(sources[-1], fps))
    best = pace.best_cover(tracks, length, pacing.covers)
    return pace.lay_along(sources[best], targets, fps, pacing.smoothing)


def steering_fit(control: Control, anchor: Anchor, skeleton: Any, frames: int,
                 method: ControlMethod) -> Callable[[np.ndarray], np.ndarray]:
    """What steering (steered.py) fits each decoded motion (network frame) to: a path's pace
    and curve (pace.lay_along, where the motion travels), then the correction's fits without
    the stance lock."""
    fits = replace(method, lock_feet=False)
    targets = None
    if control.path is not None and control.prefix is None and control.edit is None:
        world = pace.path_targets(control.path, control.path_frames, frames)
        targets = anchor.to_model(np.stack([world[:, 0], np.zeros(frames), world[:, 1]],
                                           axis=1))[:, [0, 2]]
        length = float(pace.arc_length(targets)[-1])

    def fit(joints: np.ndarray) -> np.ndarray:
        if targets is not None and pace.travels(pace.track_of(joints, skeleton.fps), length):
            joints = pace.lay_along(joints, targets, skeleton.fps,
                                    method.pacing.smoothing).joints
        return project(joints, control, anchor, skeleton, fits)
    return fit


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
    if method.guide:  # refused before any sampling where it cannot run
        require_torch("decoder guidance (ControlMethod(guide=True))")
        from mlct.generate.control.sampled import guidance_decoder

        guidance_decoder(pipe)
    anchor = anchor_of(control, skeleton)
    laid = paced(pipe, text, frames, control, nfe, seed, method.pacing) \
        if method.pace and not method.steer else None
    stood = None  # the motion whose standing feet the correction holds: the one it corrects
    if method.steer:
        require_torch("steering (ControlMethod(steer=True))")
        from mlct.generate.control.steered import decode, steered_latent

        fit = steering_fit(control, anchor, skeleton, frames, method)
        z = steered_latent(pipe, text, frames, seed, nfe, fit, method.steered_steps)
        joints, feats = decode(pipe, z, frames), None
    elif laid is not None:
        joints, feats, stood = anchor.to_model(laid.joints), None, laid.retimed
    else:  # sampled: candidates and guidance run the networks through torch
        require_torch("this control (keyframes, an edit, a prefix, or a path for a text that "
                      "does not travel)")
        from mlct.generate.control.sampled import guided_latent, targets_of
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
