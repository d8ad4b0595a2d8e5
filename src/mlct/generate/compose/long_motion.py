"""Long motions: one continuous motion from several prompts, past the model's 196-frame window.

Each prompt is generated as its own segment (all in one batch), then the segments are chained:
- segment k+1 is turned about the vertical axis and moved so that its first frame stands where,
  and faces where, segment k stands at the start of their overlap: root track and heading carry
  on from one segment to the next;
- in the overlap (`blend` frames, generated in addition to the requested lengths) the poses in
  the body's frame, the root's velocity and the rate of turn are cross-faded with smoothstep
  weights, so that position and velocity change continuously at the seam.

`seam_speeds` measures the result: the joint speeds around each seam against the range of speeds
of the segments themselves, as the model generated them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ContextManager, Protocol, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.generate.control.facing import heading
from mlct.generate.output.generated import GeneratedMotion
from mlct.motion.skeleton import Skeleton



class SegmentMaker(Protocol):
    """What chaining needs of a generator (compose.generator.MotionGenerator, which also calls
    generate_long for prompts that name actions in sequence: a Protocol, not an import)."""

    skeleton: Skeleton

    @property
    def max_frames(self) -> int: ...

    def _lengths(self, count: int, lengths: Any, seconds: Any, longest: int | None = None
                 ) -> list[int]: ...

    def longest_gait(self) -> int: ...

    def generate(self, texts: Any, lengths: Any = None, seconds: Any = None, nfe: Any = None,
                 seed: Any = None, guidance: Any = None, split_actions: bool = True,
                 candidates: Any = None) -> Any: ...

    def parts_of_a_whole(self) -> ContextManager[None]: ...

    def plant_feet(self, motion: Any) -> Any: ...


BLEND_SECONDS = 0.75  # the shortest that kept seam speeds within the segments' (measured once)


def blend_frames(fps: float, seconds: float = BLEND_SECONDS) -> int:
    """The frames two chained segments overlap by (at least 2)."""
    return max(2, int(round(seconds * fps)))


@dataclass
class LongMotion(GeneratedMotion):
    """A chained motion; seams are the frames where each later segment's blend starts."""

    seams: tuple[int, ...] = ()
    texts: tuple[str, ...] = ()
    blend: int = 0
    segments: tuple[np.ndarray, ...] = ()  # the joints of each segment as generated


def _turn_y(points: np.ndarray, angle: float) -> np.ndarray:
    cos, sin = np.cos(angle), np.sin(angle)
    x, z = points[..., 0], points[..., 2]
    return np.stack([cos * x + sin * z, points[..., 1], -sin * x + cos * z], axis=-1)


def _decompose(joints: np.ndarray, skeleton: Skeleton
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, J, 3) -> root xz track (T, 3) with y = 0, unwrapped heading (T,), and the pose in the
    body's own frame (T, J, 3): root at the xz origin, facing +Z."""
    root = joints[:, 0] * np.array([1.0, 0.0, 1.0])
    angle = np.unwrap(heading(joints, skeleton))
    local = _turn_y(joints - root[:, None], -angle[:, None])
    return root, angle, local


def _compose(root: np.ndarray, angle: np.ndarray, local: np.ndarray) -> np.ndarray:
    return _turn_y(local, angle[:, None]) + root[:, None]


def _continue(root0: np.ndarray, angle0: float, root: np.ndarray, angle: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """A track (root, angle) turned and moved to start at (root0, angle0)."""
    turn = angle0 - angle[0]
    return _turn_y(root - root[0], turn) + root0, angle + turn


def _rates(track: np.ndarray, n: int) -> np.ndarray:
    """Per-frame change of track over its first n frames; frame 0 takes frame 1's (it has no
    predecessor in its own segment)."""
    steps = np.diff(track[:n + 1], axis=0)
    return np.concatenate([steps[:1], steps[:n - 1]])


def chain_segments(segments: Sequence[np.ndarray], blend: int, skeleton: Skeleton
                   ) -> tuple[np.ndarray, list[int]]:
    """Chain (T_k, J, 3) segments, each overlapping the next by `blend` frames; returns the
    joints and the frame where each seam's blend starts.

    In the overlap the body-frame poses are cross-faded, and so are the root's velocity and the
    heading's rate of turn, which are then integrated: blending world positions instead would
    drag the root between two diverging tracks (one still walking, one standing) and add
    speed at the seam."""
    root, angle, local = _decompose(np.asarray(segments[0], dtype=np.float64), skeleton)
    seams = []
    s = (np.arange(blend) + 0.5) / blend
    weight = s * s * (3 - 2 * s)  # smoothstep: zero slope at both ends
    for segment in segments[1:]:
        start = len(root) - blend
        n_root, n_angle, n_local = _decompose(np.asarray(segment, dtype=np.float64), skeleton)
        n_root, n_angle = _continue(root[start], angle[start], n_root, n_angle)
        w = weight[:, None]
        mixed_local = (1 - w[:, :, None]) * local[start:] + w[:, :, None] * n_local[:blend]
        velocity = (1 - w) * np.diff(root[start - 1:], axis=0) + w * _rates(n_root, blend)
        turning = (1 - weight) * np.diff(angle[start - 1:]) + weight * _rates(n_angle, blend)
        mixed_root = root[start - 1] + np.cumsum(velocity, axis=0)
        mixed_angle = angle[start - 1] + np.cumsum(turning)
        rest_root, rest_angle = _continue(mixed_root[-1], mixed_angle[-1],
                                          n_root[blend - 1:], n_angle[blend - 1:])
        root = np.concatenate([root[:start], mixed_root, rest_root[1:]])
        angle = np.concatenate([angle[:start], mixed_angle, rest_angle[1:]])
        local = np.concatenate([local[:start], mixed_local, n_local[blend:]])
        seams.append(start)
    return _compose(root, angle, local), seams


def generate_long(generator: SegmentMaker, texts: Sequence[str], seconds: Sequence[float],
                  nfe: int | None = None, seed: int | None = None,
                  blend_seconds: float = BLEND_SECONDS, guidance: float | None = None,
                  candidates: int | None = None) -> LongMotion:
    """One continuous motion doing texts[k] for seconds[k], in order; candidates: per
    segment, as MotionGenerator.generate's (None: the model's default)."""
    if len(texts) != len(seconds):
        raise MlctError(f"{len(texts)} prompts but {len(seconds)} durations; give one each")
    fps = generator.skeleton.fps
    blend = blend_frames(fps, blend_seconds)
    frames = generator._lengths(len(texts), None, seconds, generator.longest_gait())
    # every segment but the last also covers the next one's blend
    lengths = [n + blend for n in frames[:-1]] + [frames[-1]]
    # A gait may go past the window when the generator keeps gaits going (generate/
    # compose/keep_going.py); generate() itself refuses any other segment that long.
    if max(lengths) > generator.longest_gait():
        raise MlctError(f"a segment may last at most {(generator.max_frames - blend) / fps:.1f} s "
                        f"(the model's window, less the {blend / fps:.1f} s blend); split it")
    with generator.parts_of_a_whole():  # the chain is planted, not each part
        parts = generator.generate(list(texts), lengths=lengths, nfe=nfe, seed=seed,
                                   guidance=guidance, split_actions=False, candidates=candidates)
    joints, seams = chain_segments([p.joints for p in parts], blend, generator.skeleton)
    # features=None: derived from the joints when read (generated.py)
    motion = LongMotion(text=" / ".join(texts), features=None, joints=joints.astype(np.float32),
                        fps=fps, skeleton=generator.skeleton.name, seed=parts[0].seed,
                        seams=tuple(seams), texts=tuple(texts), blend=blend,
                        segments=tuple(p.joints for p in parts))
    return generator.plant_feet(motion)


def _speeds(joints: np.ndarray, fps: float) -> np.ndarray:
    return np.linalg.norm(np.diff(joints, axis=0), axis=-1) * fps  # (T-1, J) m/s


def seam_speeds(motion: LongMotion) -> dict[str, float]:
    """The largest joint speed (m/s) in the seams' blend windows, against the largest and the
    99th-percentile speed of the segments as the model generated them."""
    speed = _speeds(motion.joints, motion.fps)
    at_seam = np.zeros(len(speed), dtype=bool)
    for start in motion.seams:
        at_seam[max(0, start - 1):start + motion.blend] = True
    own = np.concatenate([_speeds(s, motion.fps).ravel() for s in motion.segments])
    return {"seam_max": float(speed[at_seam].max()) if at_seam.any() else 0.0,
            "segments_max": float(own.max()), "segments_p99": float(np.percentile(own, 99))}
