"""A path met by the text's own motion: re-timed to the path's pace and laid along it.

Why (docs/control.md, `bench/control.py --speeds`): a path asking for another speed than the
text's motion has was met by moving the body, and the feet slid. Guidance through the decoder
(gradient steps on each consistency step's clean latent) could not change the pace enough: one
latent holds about as many strides whatever length it is decoded at (the decoder spreads them
over the frames), and even 60 gradient steps on the last latent left a walk asked for twice its
speed 0.8 m from the path on average. The text's own motion can do it when it is as long as the
path needs, in three steps:

1. `track_of`: how far the motion goes: its root's progress along its own smoothed track;
2. the caller makes the text's motion `frames_to_cover` frames long, the length at which it
   covers the path at its own pace (the pipeline keeps a gait going past its natural length);
3. `lay_along`: frame t of the result is the source's frame at which the source's progress is
   the path's at t (a monotone time-warp: the legs' own strides carry the body, so the cadence
   follows the pace and a standing foot stays standing), turned and moved as one rigid body so
   that the source's track lies along the path.

Steering the latent inside the consistency steps by this re-timing could not either
(steered.py): the autoencoder's encoder gives back a re-timed motion as one that hardly moves.

A motion that hardly travels (`travels`: a wave, a jump on the spot) is left to the correction
(fit.py), which moves it along the path. Pure numpy: no network, any backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from mlct.generate.control.fit import turn_y

TRACK_SECONDS = 0.5  # s: the smoothing (Gaussian sigma) that takes a stride's sway off the root
TURN_METRES = 0.15  # m: a path's heading is smoothed over this much of it (corners turn in a step)
# a motion that goes less than MIN_TRAVEL m, or less than MIN_SHARE of the path, does not walk
# it: the correction moves it along
MIN_TRAVEL = 0.3
MIN_SHARE = 0.25
SPARE = 1.15  # the source is made this much longer than the path needs: its end stops early
MAX_FACTOR = 3.0  # the source is at most this many times the result's length
# A source going at least COVERS of the path is re-timed as it is (a longer one has its end
# cut: the pace is the path's either way); a shorter one is made again at the length its pace
# says (at most REMAKES times: the distance a motion covers is not quite proportional to its
# length, and the start from rest and the stop weigh less). 1: a source 3 % short (0.97 before)
# held its last frame while the correction slid it the last 11 cm (an S-shaped walk's last
# waypoint); made again, the largest waypoint error before the correction fell from 11.2 to
# 2.1 cm over 32 seeds (bench/control.py --speeds) at the same median time
COVERS = 1.0
REMAKES = 1
# frames (Gaussian sigma of the time-warp, in the result's frames): a warp smoothed more than a
# frame or so flattens the stride's own rhythm of progress at a fast pace, and the root's
# progress, put back on the path's pace by moving the body, then slid the standing feet (a jog
# at 2x: +-2 cm a frame, skating 0.41 at 1 frame against 0.32 at 0.75 over 48 seeds; at 0.5
# and 0 the jogs skate less still but a walk at 1.5x or 2x more; docs/control.md)
RETIME_SMOOTHING = 0.75


@dataclass(frozen=True)
class Pacing:
    """How a path's source is made long enough and re-timed (controlled.ControlMethod.pacing;
    the default is the one bench/control.py --speeds measured best)."""

    covers: float = COVERS  # a source going less than this share of the path is made again
    smoothing: float = RETIME_SMOOTHING  # frames: the time-warp's Gaussian sigma


@dataclass(frozen=True)
class Track:
    """Where a motion goes: its root's smoothed track and how far along it the root is."""

    centre: np.ndarray  # (T, 2) xz of the smoothed root
    length: np.ndarray  # (T,) arc length of the centre from frame 0 (m)
    direction: np.ndarray  # (T,) heading of the centre's travel (radians, 0 along +Z, unwrapped)
    progress: np.ndarray  # (T,) the root's place along the track (m), never decreasing

    @property
    def distance(self) -> float:
        return float(self.progress[-1] - self.progress[0])


def arc_length(points: np.ndarray) -> np.ndarray:
    """(N, 2) polyline -> (N,) arc length from its first point."""
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]


def _unwrapped(angles: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Angles (T,) unwrapped through the `known` frames and held across the others."""
    if not known.any():
        return np.zeros(len(angles))
    t = np.arange(len(angles))
    return np.interp(t, t[known], np.unwrap(angles[known]))


def smooth_track(points: np.ndarray, sigma: float) -> np.ndarray:
    """(T, C) smoothed by a Gaussian of `sigma` frames, padded at each end by the points'
    reflection through the end point, so that a steady walk's track runs on to its ends (a
    padding that repeats the end point would bend the track's pace there)."""
    pad = min(len(points) - 1, int(3 * sigma) + 1)
    if pad < 1:
        return points.copy()
    head = 2 * points[0] - points[pad:0:-1]
    tail = 2 * points[-1] - points[-2:-pad - 2:-1]
    padded = np.concatenate([head, points, tail])
    return gaussian_filter1d(padded, sigma, axis=0, mode="nearest")[pad:pad + len(points)]


def track_of(joints: np.ndarray, fps: float) -> Track:
    """The track of a (T, J, 3) motion (root first, y up)."""
    root = np.asarray(joints, dtype=np.float64)[:, 0, [0, 2]]  # (T, 2)
    centre = smooth_track(root, TRACK_SECONDS * fps)
    velocity = np.gradient(centre, axis=0) if len(root) > 1 else np.zeros_like(root)
    moving = np.linalg.norm(velocity, axis=1) > 0.05 / fps  # 5 cm/s: standing still otherwise
    direction = _unwrapped(np.arctan2(velocity[:, 0], velocity[:, 1]), moving)
    tangent = np.stack([np.sin(direction), np.cos(direction)], axis=1)  # heading 0 is +Z
    length = arc_length(centre)
    progress = length + ((root - centre) * tangent).sum(axis=1)  # the root ahead of its centre
    return Track(centre, length, direction, np.maximum.accumulate(progress))


def path_targets(path: np.ndarray, path_frames: np.ndarray, frames: int) -> np.ndarray:
    """(frames, 2): the root's xz at every frame, straight between the waypoints at their pace
    (held before the first and after the last)."""
    t = np.arange(frames)
    return np.stack([np.interp(t, path_frames, path[:, 0]),
                     np.interp(t, path_frames, path[:, 1])], axis=1)


def travels(track: Track, path_length: float) -> bool:
    """Whether a motion going `track` can walk a path of `path_length` m (re-timed)."""
    return track.distance >= max(MIN_TRAVEL, MIN_SHARE * path_length)


def covers(track: Track, path_length: float, share: float = COVERS) -> bool:
    """Whether a source going `track` goes far enough (`share` of it) for a path of
    `path_length` m."""
    return track.distance >= share * path_length


def best_cover(tracks: list[Track], path_length: float, share: float = COVERS) -> int:
    """Which of several sources' tracks to re-time: the first that covers the path, else the
    one that goes furthest."""
    for k, track in enumerate(tracks):
        if covers(track, path_length, share):
            return k
    return int(np.argmax([t.distance for t in tracks]))


def frames_to_cover(track: Track, frames: int, path_length: float) -> int:
    """The length of a source motion of the text that covers `path_length` at the pace of the
    motion `track` was taken from (`frames` long), with SPARE, at most MAX_FACTOR times."""
    factor = min(path_length / max(track.distance, 1e-6), MAX_FACTOR)
    return max(2, int(round(frames * factor * SPARE)))


def _along(points: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (A, 2) and headings (A,) of polyline `points` at arc lengths `at`; the heading
    smoothed over TURN_METRES, so a corner turns over a step or two instead of at once."""
    s = arc_length(points)
    keep = np.r_[True, np.diff(s) > 1e-9]
    points, s = points[keep], s[keep]
    if len(s) < 2:  # a path that stands still: stand, facing +Z
        return np.repeat(points[:1], len(at), axis=0), np.zeros(len(at))
    xz = np.stack([np.interp(at, s, points[:, 0]), np.interp(at, s, points[:, 1])], axis=1)
    step = np.diff(points, axis=0)
    heading = np.unwrap(np.arctan2(step[:, 0], step[:, 1]))  # (N-1,) per segment
    grid_step = 0.01
    grid = np.arange(0.0, s[-1] + grid_step, grid_step)
    smooth = gaussian_filter1d(np.interp(grid, (s[1:] + s[:-1]) / 2, heading),
                               TURN_METRES / grid_step, mode="nearest")
    return xz, np.interp(at, grid, smooth)


def _frames_at(joints: np.ndarray, at: np.ndarray) -> np.ndarray:
    """(T, J, 3) sampled at fractional frames `at` (A,) by linear interpolation."""
    low = np.clip(np.floor(at).astype(int), 0, len(joints) - 1)
    high = np.minimum(low + 1, len(joints) - 1)
    w = np.clip(at - low, 0.0, 1.0)[:, None, None]
    return (1 - w) * joints[low] + w * joints[high]


@dataclass(frozen=True)
class Laid:
    """A source motion re-timed to a path and laid along it."""

    joints: np.ndarray  # (T, J, 3) in the path's world
    retimed: np.ndarray  # (T, J, 3) the same frames where the source was: its feet stand when
    # they stood in the source (laying along a curve turns a standing foot with the body)


def lay_along(source: np.ndarray, targets: np.ndarray, fps: float,
              smoothing: float = RETIME_SMOOTHING) -> Laid:
    """The source motion (S, J, 3) re-timed to the root targets (T, 2) (path_targets) and laid
    along them, the time-warp smoothed by `smoothing` frames (no jerks where the source's root
    stalls). Where the source goes less far than the targets, its last frame is held where it
    ends (the correction then closes the gap)."""
    source = np.asarray(source, dtype=np.float64)
    track = track_of(source, fps)
    frame = np.arange(len(source), dtype=np.float64)
    rising = np.r_[True, np.diff(track.progress) > 1e-9]
    gone = track.progress - track.progress[0]  # (S,) how far the source's root has gone
    # (T,) how far along the path the root is at each frame, as far as the source goes
    wanted = np.minimum(arc_length(targets), gone[-1])
    warp = np.interp(wanted, gone[rising], frame[rising])  # (T,) source frames
    warp = smooth_track(np.maximum.accumulate(warp)[:, None], smoothing)[:, 0]  # no jerks
    retimed = _frames_at(source, warp)
    out = retimed.copy()
    centre = np.stack([np.interp(warp, frame, track.centre[:, k]) for k in (0, 1)], axis=1)
    # the centre goes where the path is as far along as the centre is along its own track,
    # shifted by what the warp's smoothing left between the root's progress and the path's
    reach = np.interp(warp, frame, track.length) + wanted - np.interp(warp, frame, track.progress)
    place, heading = _along(targets, reach)
    out[..., 0] -= centre[:, None, 0]
    out[..., 2] -= centre[:, None, 1]
    out = turn_y(out, (heading - np.interp(warp, frame, track.direction))[:, None])
    out[..., 0] += place[:, None, 0]
    out[..., 2] += place[:, None, 1]
    return Laid(out, retimed)
