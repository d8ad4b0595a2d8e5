"""Planted feet stay planted: foot-contact cleanup of joint-position motions.

A generated foot that should stand on the floor drifts a few centimetres per step (so do the
benchmark's own motions: their in-contact toe speed is what the model learnt). This module finds
each foot's contact spans from the joints alone (the toe low and slow) and pins the foot there:
the toe's ground position is held at its mean over the span, the correction fades in and out over
a few frames around it, and the leg follows by two-bone inverse kinematics from the hip (thigh
and shin keep each frame's own lengths, the knee bends in the plane it bent in). The pelvis and
the rest of the body are not moved, and the toe keeps its height; where a near-straight leg
cannot reach the hold, the heel rises a little (at most max_lift) or the hold is shortened.

Joints are (T, J, 3), y up, the floor at y = 0, in the skeleton's unit (thresholds are given in
metres and seconds and scaled, as in physics.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from mlct.motion.skeleton import Skeleton, units_per_metre


# m: a heel on the floor has its ankle joint under this (the benchmark's standing ankles: 4-8 cm)
ANKLE_HEIGHT = 0.10


@dataclass(frozen=True)
class FootLock:
    """How contacts are found and held. Defaults read the HumanML3D motions at 20 fps: a foot
    in contact has its toe under 5 cm and moving under 0.8 m/s (decoded walks slide 0.1 m/s
    on average in contact, a quarter of their contact frames over 0.5; their toes swing
    through at 2-4 m/s)."""

    height: float = 0.05  # m: a toe above this is not on the floor (GMD's skating height)
    speed: float = 0.8  # m/s: a toe faster than this is swinging, not standing
    min_frames: int = 3  # a shorter low-and-slow stretch is a brush, not a step
    blend: int = 3  # frames over which the correction fades in and out around a span
    # m: a span whose toe strays further than this from its mean is a slow step (a foot drawn
    # back into a kneel, shifted while leaning), not a slide: held, its leg would stretch
    # (10 % of the benchmark's decoded spans stray over 5 cm, 1 % over 12 cm)
    max_hold: float = 0.08
    # m: how far a held foot's heel may rise when its near-straight leg cannot reach the hold
    # (the toe stays down); past it the hold is shortened
    max_lift: float = 0.03


def contact_spans(joints: np.ndarray, skeleton: Skeleton, toe: int, settings: FootLock,
                  fps: float | None = None) -> list[tuple[int, int]]:
    """[start, end) frame spans where the toe joint `toe` stands on the floor (low and slow
    for min_frames or more, straying at most max_hold from where it stands on average)."""
    scale = units_per_metre(skeleton)
    fps = skeleton.fps if fps is None else fps
    position = joints[:, toe]
    if len(position) < 2:
        return []
    speed = np.linalg.norm(np.gradient(position[:, [0, 2]], axis=0), axis=-1) * fps / scale
    standing = (position[:, 1] / scale < settings.height) & (speed < settings.speed)
    spans, start = [], None
    for t, on in enumerate(np.append(standing, False)):
        if on and start is None:
            start = t
        elif not on and start is not None:
            ground = position[start:t][:, [0, 2]]
            stray = np.linalg.norm(ground - ground.mean(axis=0), axis=-1).max() / scale
            if t - start >= settings.min_frames and stray <= settings.max_hold:
                spans.append((start, t))
            start = None
    return spans


def foot_contacts(joints: np.ndarray, skeleton: Skeleton, settings: FootLock | None = None,
                  fps: float | None = None) -> np.ndarray:
    """(T, 2) bool: the left and the right foot on the floor, frame by frame: its toe or its
    heel (the ankle, under ANKLE_HEIGHT) low and slow for min_frames or more, as contact_spans;
    a slow step counts, however far it strays. The labels a retargeting or a physics
    controller takes; the heel makes a walk's double support, which the toe alone misses."""
    settings = FootLock() if settings is None else settings
    toes = dataclasses.replace(settings, max_hold=np.inf)
    heels = dataclasses.replace(toes, height=ANKLE_HEIGHT)
    joints = np.asarray(joints, np.float64)
    out = np.zeros((len(joints), 2), dtype=bool)
    for side, (_, toe) in enumerate((skeleton.foot_left, skeleton.foot_right)):
        ankle = _leg(skeleton, toe)[2]
        for joint, rule in ((toe, toes), (ankle, heels)):
            for start, end in contact_spans(joints, skeleton, joint, rule, fps):
                out[start:end, side] = True
    return out


def _smoothstep(x: np.ndarray) -> np.ndarray:
    return x * x * (3.0 - 2.0 * x)


def correction(toe_xz: np.ndarray, spans: list[tuple[int, int]], blend: int) -> np.ndarray:
    """(T, 2) ground offsets that hold the toe at its mean position over each span and fade to
    zero (or into the next span's offset, when the gap is short) around it."""
    frames = len(toe_xz)
    offset = np.zeros((frames, 2))
    for start, end in spans:
        offset[start:end] = toe_xz[start:end].mean(axis=0) - toe_xz[start:end]
    edges = [(None, None)] + spans + [(None, None)]
    for (_, gap_start), (gap_end, _) in zip(edges[:-1], edges[1:]):
        gap_start = 0 if gap_start is None else gap_start
        gap_end = frames if gap_end is None else gap_end
        if gap_end <= gap_start:
            continue
        before = offset[gap_start - 1] if gap_start > 0 else np.zeros(2)
        after = offset[gap_end] if gap_end < frames else np.zeros(2)
        t = np.arange(gap_start, gap_end)
        if gap_end - gap_start <= 2 * blend and gap_start > 0 and gap_end < frames:
            # a short lift between two contacts: one offset slides into the next
            w = _smoothstep((t - gap_start + 1) / (gap_end - gap_start + 1))[:, None]
            offset[gap_start:gap_end] = (1 - w) * before + w * after
            continue
        fade_out = _smoothstep(np.clip(1 - (t - gap_start + 1) / (blend + 1), 0, 1))[:, None]
        fade_in = _smoothstep(np.clip(1 - (gap_end - t) / (blend + 1), 0, 1))[:, None]
        offset[gap_start:gap_end] = fade_out * before + fade_in * after
    return offset


def two_bone_ik(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, target: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(knee, ankle) per frame: the ankle moved to `target` (or as near as the leg reaches),
    thigh and shin keeping their lengths, the knee in the plane of its old bend."""
    thigh = np.linalg.norm(knee - hip, axis=-1, keepdims=True)
    shin = np.linalg.norm(ankle - knee, axis=-1, keepdims=True)
    reach = target - hip
    distance = np.linalg.norm(reach, axis=-1, keepdims=True)
    direction = reach / np.maximum(distance, 1e-9)
    # a straight leg cannot reach further, a folded one not nearer; 0.1 % short of straight
    # keeps the knee's bend direction defined
    distance = np.clip(distance, np.abs(thigh - shin) * 1.001 + 1e-9, (thigh + shin) * 0.999)
    # the pole: where the knee stood off the old hip-ankle line, made square to the new one
    old_axis = ankle - hip
    old_axis = old_axis / np.maximum(np.linalg.norm(old_axis, axis=-1, keepdims=True), 1e-9)
    pole = (knee - hip) - ((knee - hip) * old_axis).sum(-1, keepdims=True) * old_axis
    bend = pole - (pole * direction).sum(-1, keepdims=True) * direction
    # a leg that was straight: bend towards where the ankle was
    fallback = old_axis - (old_axis * direction).sum(-1, keepdims=True) * direction
    bend = np.where(np.linalg.norm(bend, axis=-1, keepdims=True) > 1e-6, bend, fallback)
    bend = bend / np.maximum(np.linalg.norm(bend, axis=-1, keepdims=True), 1e-9)
    cos_hip = np.clip((thigh**2 + distance**2 - shin**2) / (2 * thigh * distance), -1.0, 1.0)
    new_knee = hip + thigh * (cos_hip * direction + np.sqrt(1 - cos_hip**2) * bend)
    return new_knee, hip + distance * direction


def lock_feet(joints: np.ndarray, skeleton: Skeleton, settings: FootLock | None = None,
              fps: float | None = None) -> np.ndarray:
    """The motion with each foot pinned to the floor over its contact spans (a new array)."""
    settings = FootLock() if settings is None else settings
    out = np.array(joints, dtype=np.float64, copy=True)
    if out.ndim != 3 or out.shape[1:] != (skeleton.n_joints, 3):
        raise ValueError(f"expected joints of shape (T, {skeleton.n_joints}, 3) for "
                         f"{skeleton.name}, got {out.shape}")
    for _, toe in (skeleton.foot_left, skeleton.foot_right):
        hip, knee, ankle = _leg(skeleton, toe)
        spans = contact_spans(out, skeleton, toe, settings, fps)
        if not spans:
            continue
        offset = correction(out[:, toe, [0, 2]], spans, settings.blend)
        # A stance leg is near straight: a hold it cannot reach raises the heel a little (the
        # toe stays down, as in a push-off), or, past max_lift, is shortened. Pointing a straight
        # leg at it instead lifted the whole foot: a walk with a flight phase.
        fraction, lift = _within_reach(out[:, hip], out[:, knee], out[:, ankle], offset,
                                       settings.max_lift * units_per_metre(skeleton))
        offset *= fraction[:, None]
        moved = np.abs(offset).sum(-1) > 0
        target = out[moved, ankle].copy()
        target[:, [0, 2]] += offset[moved]
        target[:, 1] += lift[moved]
        new_knee, new_ankle = two_bone_ik(out[moved, hip], out[moved, knee], out[moved, ankle],
                                          target)
        foot = list(skeleton.descendants(ankle))
        shift = new_ankle - out[moved, ankle]
        shift[:, 1] -= lift[moved]  # the heel rises; the toe keeps its height
        out[np.ix_(moved, foot)] += shift[:, None]
        out[moved, knee] = new_knee
        out[moved, ankle] = new_ankle
    return out


def _within_reach(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, offset: np.ndarray,
                  max_lift: float) -> tuple[np.ndarray, np.ndarray]:
    """(fraction, lift), each (T,): the share of each frame's ground offset d to apply and how
    far to raise the ankle, so that the moved ankle is within two_bone_ik's reach R (0.1 %
    short of straight). The whole offset at the ankle's height when it reaches; else the whole
    offset with the ankle raised by the smaller root of |a + d + h y|^2 = R^2 (a = ankle -
    hip) when that is at most max_lift; else the ankle at its height and the share f, the
    larger root of |a + f d|^2 = R^2 (0 where the leg is already straight)."""
    reach = 0.999 * (np.linalg.norm(knee - hip, axis=-1) + np.linalg.norm(ankle - knee, axis=-1))
    a = ankle - hip
    d = np.zeros_like(a)
    d[:, [0, 2]] = offset
    b = a + d
    bb = (b * b).sum(-1)
    fits = bb <= reach**2
    disc = b[:, 1] ** 2 - (bb - reach**2)
    lift = -b[:, 1] - np.sqrt(np.maximum(disc, 0.0))
    raised = ~fits & (disc >= 0) & (lift >= 0) & (lift <= max_lift)
    dd, ad, aa = (d * d).sum(-1), (a * d).sum(-1), (a * a).sum(-1)
    slack = reach**2 - aa
    share = (-ad + np.sqrt(np.maximum(ad**2 + dd * slack, 0.0))) / np.maximum(dd, 1e-18)
    share = np.where(slack <= 0, 0.0, np.clip(share, 0.0, 1.0))
    return np.where(fits | raised, 1.0, share), np.where(raised, lift, 0.0)


def _leg(skeleton: Skeleton, toe: int) -> tuple[int, int, int]:
    """(hip, knee, ankle) of the leg ending in `toe`: the kinematic chain's first three joints
    after the root (HumanML3D: hip, knee, ankle, foot; KIT-ML: hip, knee, ankle, metatarsal,
    toe, whose foot pair is the metatarsal and the toe)."""
    for chain in skeleton.kinematic_chain:
        if toe in chain:
            return chain[1], chain[2], chain[3]
    raise ValueError(f"joint {toe} is on no kinematic chain of {skeleton.name}")


def contact_slide(joints: np.ndarray, skeleton: Skeleton, fps: float | None = None) -> float:
    """Mean toe speed over both feet's contact spans, m/s (0 when a standing foot stands; 0
    without contacts): the read-out of a slide. Spans that stray too far to be held count too,
    so what lock_feet leaves sliding shows."""
    settings = FootLock(max_hold=np.inf)
    fps = skeleton.fps if fps is None else fps
    moved, frames = 0.0, 0
    for _, toe in (skeleton.foot_left, skeleton.foot_right):
        for start, end in contact_spans(joints, skeleton, toe, settings, fps):
            moved += np.linalg.norm(np.diff(joints[start:end, toe][:, [0, 2]], axis=0),
                                    axis=-1).sum()
            frames += end - start - 1
    return moved / frames * fps / units_per_metre(skeleton) if frames else 0.0
