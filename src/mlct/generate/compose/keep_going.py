"""Locomotion asked for longer than the data's clips: keep going instead of stopping.

The benchmark's walks last 3.6-6.2 s, its jogs 3.2-4.0 s and its runs 2.9-3.6 s, each starting
and ending at rest, so a model asked for "a person jogs forward" for 7 s jogs about 4 s and
stands for the rest (docs/model_card.md). A user asking for 7 s of
jogging wants 7 s of jogging. So when a one-action prompt is asked for clearly longer than its
natural length (the duration model's) and the motion made from it moved and then stopped, the
prompt is made again as several segments of its natural length, chained into one motion:

- the first segment keeps its start from rest, the last its stop at the end, and the segments
  in between lose the start-up and slow-down around their moving stretch, so the speed does
  not dip at each seam;
- each seam is placed where the two segments' poses (in the body's own frame) agree best over
  the blend window, so a stride is not cross-faded with its opposite phase.

Nothing changes for a motion that is not a gait (is_gait: a jump, a turn or a spin on the spot)
or does not stop early, a prompt that names a count, a distance or a turn ("takes three
steps", "walks five meters", "turns left while walking": stopping is what it asks), or a clip
within a second of its natural length.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from mlct.generate.compose.long_motion import _decompose, chain_segments
from mlct.generate.control.facing import heading
from mlct.motion.gait import foot_swaps
from mlct.motion.skeleton import Skeleton

# A count or a distance in the prompt: the action ends when it is done.
_COUNTED = re.compile(
    r"\b(?:once|twice|thrice)\b|\b(?:\d+(?:\.\d+)?|an?|one|two|three|four|five|six|seven|eight|"
    r"nine|ten|eleven|twelve|a\s+few|several|a\s+couple\s+of)\s+(?:more\s+)?(?:times?|steps?|"
    r"strides?|paces?|laps?|rounds?|meters?|metres?|m|feet|foot|yards?|kilometers?|km)\b",
    re.IGNORECASE)
MARGIN_SECONDS = 1.0  # asked beyond the natural length by more than this to count as "longer"
MOVING_SPEED = 0.25  # m/s of the pelvis over the ground: locomotion, not a shuffle
STOPPED_SHARE = 0.3  # the last second moves at under this share of the moving speed: stopped
SMOOTH_SECONDS = 0.5  # the speed is averaged over about a stride
# A gait's pace holds: in the later half of the stretch its lower quartile is at least this
# share of its upper one (a walk's sway ~0.8); a long jump's speed peaks and falls (~0.2).
STEADY_SHARE = 0.6
# The benchmark's circles turn 360 degrees in 6-8 s (45-60 a second); its spins and turns far
# faster.
MAX_TURN_RATE = 90.0
MIN_STRAIGHTNESS = 0.7  # net over path ground travel per second: going somewhere (straightness)
MOVING_SHARE = 0.5  # a segment's moving stretch: frames at at least this share of its speed
# Steps (the lower foot changing side) a gait cut short must take through its moving stretch: a
# walk takes ~2 a second, a long jump's feet move together
MIN_STEPS = 4
# The last seam may retime the motion by up to this share of its length, so that it can be placed
# where the two takes' gaits are in phase; each 1 % of retiming costs as much as 1 mm of mean
# pose difference (MAX_WARP 5 %: within the benchmark's own tempo range, 1/1.15-1.15).
MAX_WARP = 0.05
WARP_COST = 0.1


# A turn ends when its angle is reached. One that steps around as it turns can pass for a gait
# by its pelvis (1 in 15 of the benchmark's turn paraphrases did), so the words rule it out.
_TURNING = re.compile(r"\b(?:turn(?:s|ing)?|rotat\w*|pivot\w*|spin(?:s|ning)?|twirl\w*|"
                      r"face(?:s)?|facing)\b", re.IGNORECASE)


def names_an_end(text: str) -> bool:
    """Does the prompt say when the action ends: a count, a distance, or a turn?"""
    return _COUNTED.search(text) is not None or _TURNING.search(text) is not None


def ground_speed(joints: np.ndarray, fps: float) -> np.ndarray:
    """(T, J, 3) -> (T,) the pelvis's horizontal speed in m/s, averaged over ~half a second."""
    root = np.asarray(joints, dtype=np.float64)[:, 0, [0, 2]]
    step = np.linalg.norm(np.diff(root, axis=0), axis=1) * fps
    speed = np.concatenate([step[:1], step]) if len(step) else np.zeros(len(root))
    width = max(1, int(round(SMOOTH_SECONDS * fps)))
    kernel = np.ones(width) / width
    return np.convolve(np.pad(speed, (width // 2, width - 1 - width // 2), mode="edge"),
                       kernel, mode="valid")


def straightness(joints: np.ndarray, fps: float) -> float:
    """The median, over the motion's 1-s windows, of the pelvis's net ground displacement over
    its path length: ~1 for a gait that goes somewhere (a walk's sway, a circle's 50 degrees a
    second cost little), far below for a body turning or spinning on the spot (the pelvis
    circles a few centimetres around the feet at up to 0.7 m/s)."""
    root = np.asarray(joints, dtype=np.float64)[:, 0, [0, 2]]
    width = int(round(fps))
    ratios = []
    for start in range(0, len(root) - width, max(1, width // 2)):
        window = root[start:start + width + 1]
        path = np.linalg.norm(np.diff(window, axis=0), axis=1).sum()
        if path > 1e-6:
            ratios.append(np.linalg.norm(window[-1] - window[0]) / path)
    return float(np.median(ratios)) if ratios else 0.0


def is_gait(joints: np.ndarray, fps: float, natural_seconds: float, skeleton: Skeleton) -> bool:
    """The motion goes somewhere through its natural length: three quarters of that stretch
    (less half a second at each end) at MOVING_SPEED or more, at a steady pace in its later half,
    straight enough over each second and turning no faster than a circle walk: a gait, not the
    burst of one long jump (its pace rises and falls within a second) or a turn or a spin on
    the spot."""
    return _gait_pace(joints, ground_speed(joints, fps), fps, natural_seconds, skeleton) is not None


def stops_early(joints: np.ndarray, fps: float, natural_seconds: float,
                skeleton: Skeleton) -> bool:
    """A gait (is_gait) that stands still in its last second, asked for more than
    MARGIN_SECONDS longer than its natural length."""
    if len(joints) / fps < natural_seconds + MARGIN_SECONDS:
        return False
    speed = ground_speed(joints, fps)
    pace = _gait_pace(joints, speed, fps, natural_seconds, skeleton)
    return pace is not None and float(speed[-int(round(fps)):].mean()) < STOPPED_SHARE * pace


def _gait_pace(joints: np.ndarray, speed: np.ndarray, fps: float, natural_seconds: float,
               skeleton: Skeleton) -> float | None:
    """The median ground speed over the natural stretch when the motion is a gait (is_gait),
    else None; `speed` is ground_speed(joints, fps).

    A motion that fails only because it stops before the natural stretch ends (a decoder may
    end a walk's clip a few tenths of a second before the duration model's length, and the
    slowing down reads as an unsteady pace) is judged again over its moving stretch, if its
    feet alternate through it (MIN_STEPS): a long jump's burst, cut where it lands, is as
    steady, but its feet move together (docs/training.md)."""
    lead = int(round(0.5 * fps))
    end = min(int(round((natural_seconds - 0.5) * fps)), len(joints))
    pace = _pace_over(joints, speed, fps, lead, end, skeleton)
    if pace is None:
        stop = moving_stretch(joints, fps, speed)[1]
        if lead < stop < end and foot_swaps(joints[lead:stop], skeleton) >= MIN_STEPS:
            pace = _pace_over(joints, speed, fps, lead, stop, skeleton)
    return pace


def _pace_over(joints: np.ndarray, speed: np.ndarray, fps: float, lead: int, end: int,
               skeleton: Skeleton) -> float | None:
    """_gait_pace's test over frames [lead, end)."""
    stretch = speed[lead:end]
    if len(stretch) < fps:  # under a second of it: no gait to judge
        return None
    later = stretch[len(stretch) // 2:]  # past a run's 1.5 s of speeding up
    gait = (float(np.percentile(stretch, 25)) >= MOVING_SPEED
            and float(np.percentile(later, 25)) >= STEADY_SHARE * float(np.percentile(later, 75))
            and straightness(joints[lead:end], fps) >= MIN_STRAIGHTNESS
            and turn_rate(joints[lead:end], fps, skeleton) <= MAX_TURN_RATE)
    return float(np.median(stretch)) if gait else None


def turn_rate(joints: np.ndarray, fps: float, skeleton: Skeleton) -> float:
    """The mean rate of turn about the vertical, degrees a second (the facing's net change over
    the stretch's duration): a spin's 200 and more against a circle's 50-60."""
    angle = np.unwrap(heading(np.asarray(joints, dtype=np.float64), skeleton))
    return float(np.degrees(abs(angle[-1] - angle[0])) * fps / max(len(angle) - 1, 1))


def segment_count(frames: int, natural_frames: int, blend: int) -> int:
    """Takes of natural_frames enough for frames, on the safe side: each take after the first
    adds its moving stretch (the take less its start-up and slow-down, counted as half of it)
    less the blend; one more, since a stretch is known only once the take is made."""
    gain = max(natural_frames - natural_frames // 2 - blend, 1)
    return max(2, math.ceil((frames - natural_frames) / gain) + 2)


def floor_height(joints: np.ndarray, skeleton: Skeleton) -> float:
    """The take's floor: the median height of its lowest foot joint (ankles and toes)."""
    feet = list(skeleton.foot_left) + list(skeleton.foot_right)
    return float(np.median(np.asarray(joints)[:, feet, 1].min(axis=1)))


def moving_stretch(joints: np.ndarray, fps: float, speed: np.ndarray | None = None
                   ) -> tuple[int, int]:
    """[first, last) frames of a segment that move at MOVING_SHARE of its median moving speed;
    speed: ground_speed(joints, fps), when the caller has it."""
    speed = ground_speed(joints, fps) if speed is None else speed
    moving = speed[speed >= MOVING_SPEED]
    if len(moving) == 0:
        return 0, len(joints)
    fast = np.flatnonzero(speed >= MOVING_SHARE * float(np.median(moving)))
    return int(fast[0]), int(fast[-1]) + 1


def _knees_and_hips(skeleton: Skeleton) -> list[int]:
    """The joints between the pelvis and the ankles on both legs' chains."""
    feet = {skeleton.foot_left[0], skeleton.foot_right[0]}
    out = []
    for ankle in feet:
        joint = skeleton.parents[ankle]
        while joint > 0:
            out.append(joint)
            joint = skeleton.parents[joint]
    return sorted(set(out))


def _windows(x: np.ndarray, blend: int) -> np.ndarray:
    """(L, J, 3) -> (L - blend + 1, blend, J, 3): every run of `blend` frames, as a view."""
    return np.lib.stride_tricks.sliding_window_view(x, blend, axis=0).transpose(0, 3, 1, 2)


def _pose_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean joint distance of (..., blend, J, 3) pose windows, broadcast: (...)."""
    return np.linalg.norm(a - b, axis=-1).mean(axis=(-2, -1))


@dataclass(frozen=True)
class _Piece:
    segment: int  # which segment
    start: int  # [start, end) frames of it
    end: int


def _positions(pieces: list[_Piece], blend: int) -> list[int]:
    """Each piece's first frame in the chain (consecutive pieces overlap by `blend`)."""
    out, at = [], 0
    for piece in pieces:
        out.append(at)
        at += piece.end - piece.start - blend
    return out


def _cut(pieces: list[_Piece], cut: int, blend: int) -> list[_Piece] | None:
    """The pieces of a chain truncated to its first `cut` frames; None when the piece cut would
    be too short to blend into the one after it."""
    for index, (piece, at) in enumerate(zip(pieces, _positions(pieces, blend))):
        if at + piece.end - piece.start >= cut:
            kept = cut - at
            if kept < 2 * blend and index > 0:
                return None
            return pieces[:index] + [_Piece(piece.segment, piece.start, piece.start + kept)]
    return None


def keep_going(segments: Sequence[np.ndarray], frames: int, blend: int, skeleton: Skeleton
               ) -> tuple[np.ndarray, list[int]] | None:
    """((frames, J, 3) joints, the frames where each seam's blend starts): the segments (takes
    of the same prompt at its natural length) chained as one continuing motion: the first from
    its start, the last to its end, the moving stretches in between; each seam at the offset
    (within a stride) whose body-frame poses agree best over the blend window. None when the
    segments do not reach `frames`."""
    fps = skeleton.fps
    search = int(round(1.2 * fps))  # about one stride of a walk
    if len(segments) < 2:
        return None
    # One floor for all: each take lifted or lowered to the first's, else a take standing 2 cm
    # higher than the one before walks on air (a flight phase in a walk).
    floor = floor_height(segments[0], skeleton)
    segments = [np.asarray(seg, dtype=np.float64)
                + np.array([0.0, floor - floor_height(seg, skeleton), 0.0]) for seg in segments]
    # The seams are matched on the legs and the pelvis: the gait's phase.
    legs = [0, *skeleton.foot_left, *skeleton.foot_right, *_knees_and_hips(skeleton)]
    local = [_decompose(seg, skeleton)[2][:, legs] for seg in segments]
    stretches = [moving_stretch(seg, fps) for seg in segments]

    def match(tail: np.ndarray, k: int, starts: range) -> tuple[float, int]:
        """The start among `starts` whose blend window of take k is nearest `tail`."""
        valid = range(starts[0], min(starts[-1] + 1, len(local[k]) - blend + 1))
        if not valid:
            return math.inf, starts[0]
        distances = _pose_distances(_windows(local[k], blend)[valid[0]:valid[-1] + 1], tail)
        best = int(np.argmin(distances))  # the first of equals, as the starts go up
        return float(distances[best]), valid[best]

    # The first piece from the start; then middle pieces, each starting where its pose matches
    # the chain's last blend frames, until the last segment can finish the clip.
    last = len(segments) - 1
    pieces = [_Piece(0, 0, stretches[0][1])]
    lead_last = len(segments[last]) - stretches[last][0]  # the last segment from its stretch
    for k in range(1, last):
        at = _positions(pieces, blend)[-1] + pieces[-1].end - pieces[-1].start
        if at - blend + lead_last >= frames + search:
            break
        first, end = stretches[k]
        if end - first < 2 * blend + 2:
            continue  # a take that hardly moved: skip it
        tail = local[pieces[-1].segment][pieces[-1].end - blend:pieces[-1].end]
        _, s = match(tail, k, range(first, max(first + 1, min(first + search,
                                                                   end - 2 * blend))))
        pieces.append(_Piece(k, s, end))
    # The last seam: cut the chain at c and start the last take at s. Its length would be
    # c - blend + len(last) - s; c and s each range over about a stride, so the pair whose poses
    # agree best is chosen among those within MAX_WARP of `frames`, and the chain is then
    # retimed to `frames` exactly (a tempo change of a few per cent). Tying c to s instead, to
    # hit the length exactly, would fix the two takes' relative phase (both advance together).
    positions = _positions(pieces, blend)
    length = positions[-1] + pieces[-1].end - pieces[-1].start
    chain = np.concatenate([local[p.segment][p.start:p.end - (blend if i < len(pieces) - 1
                                                                  else 0)]
                            for i, p in enumerate(pieces)])
    first_last = stretches[last][0]
    slack = max(1, min(int(MAX_WARP * frames), search))  # a stride's freedom is enough
    starts = np.arange(first_last, min(first_last + search, len(segments[last]) - blend - 1))
    if not len(starts):
        return None
    exact = frames + blend - (len(segments[last]) - starts)  # (S,) the c needing no retiming
    cuts = exact[:, None] + np.arange(-slack, slack + 1)[None]  # (S, W) c within the warp
    allowed = (cuts >= blend + 1) & (cuts <= length)
    kept_at = {int(c): _cut(pieces, int(c), blend) for c in np.unique(cuts[allowed])}
    allowed &= np.isin(cuts, [c for c, kept in kept_at.items() if kept is not None])
    if not allowed.any():
        return None
    # score[s, c]: the poses' disagreement over the blend plus the retiming's cost; the pair
    # with the least, the first of equals in the order (s, then c) going up
    at = np.where(allowed, cuts, blend + 1) - blend  # a harmless window where not allowed
    score = (_pose_distances(_windows(chain, blend)[at],
                             _windows(local[last], blend)[starts][:, None])
             + WARP_COST * np.abs(cuts - exact[:, None]) / frames)
    si, wi = np.unravel_index(int(np.argmin(np.where(allowed, score, np.inf))), score.shape)
    kept, s = kept_at[int(cuts[si, wi])], int(starts[si])
    parts = [np.asarray(segments[p.segment])[p.start:p.end] for p in kept]
    parts.append(np.asarray(segments[last])[s:])
    joints, seams = chain_segments(parts, blend, skeleton)
    scale = (frames - 1) / max(len(joints) - 1, 1)
    return retime(joints, frames), [int(round(seam * scale)) for seam in seams]


@dataclass(frozen=True)
class KeptGoing:
    """A gait made again as takes chained into one continuing motion (continue_gait)."""

    joints: np.ndarray  # (frames, J, 3)
    seams: list[int]  # where each seam's blend starts
    takes: list[np.ndarray]  # the takes' joints, as made
    take_frames: int  # each take's length: the natural length, within the window


def takes_needed(joints: np.ndarray, frames: int, window: int, natural_seconds: float,
                 blend: int, skeleton: Skeleton) -> tuple[int, int] | None:
    """(count, take frames) of the takes continue_gait will first ask make_takes for, or None
    when the motion stays as made: asked past the window, a gait (is_gait) is made again as
    takes; within it, a gait that stops early (stops_early) is."""
    fps = skeleton.fps
    if frames > window:
        if not is_gait(joints, fps, natural_seconds, skeleton):
            return None
    elif not stops_early(joints, fps, natural_seconds, skeleton):
        return None
    take = min(int(round(natural_seconds * fps)), window)
    return segment_count(frames, take, blend), take


def continue_gait(joints: np.ndarray, frames: int, window: int, natural_seconds: float,
                  blend: int, skeleton: Skeleton,
                  make_takes: Callable[[int, int], Sequence[np.ndarray]]) -> KeptGoing | None:
    """One prompt's motion, made at min(frames, window), and what keeping it going makes of it
    (takes_needed says whether and how many). make_takes(count, take_frames) makes `count`
    takes of the prompt (take k with its seed + k). None: the motion stays as made; past the
    window that is the caller's refusal (no gait, or takes that did not reach the length). The
    pipeline (gaits.keep_going) and the page's reference (serve/site/reference.py) both
    call it."""
    needed = takes_needed(joints, frames, window, natural_seconds, blend, skeleton)
    if needed is None:
        return None
    count, take = needed
    for count in (count, 2 * count):  # twice as many when the stretches fell short
        takes = [np.asarray(t) for t in make_takes(count, take)]
        chained = keep_going(takes, frames, blend, skeleton)
        if chained is not None:
            return KeptGoing(chained[0], chained[1], takes, take)
    return None


def retime(joints: np.ndarray, frames: int) -> np.ndarray:
    """(T, J, 3) -> (frames, J, 3), the same motion at a uniformly changed tempo (linear
    interpolation between frames)."""
    if len(joints) == frames:
        return joints
    at = np.linspace(0.0, len(joints) - 1, frames)
    low = np.floor(at).astype(int)
    high = np.minimum(low + 1, len(joints) - 1)
    w = (at - low)[:, None, None]
    return (1 - w) * joints[low] + w * joints[high]


def portable_rules() -> dict:
    """This module's patterns and constants as JSON, for the static site's port of it
    (serve/site/static/keepgoing.js); both patterns are case-insensitive."""
    assert _COUNTED.flags & re.IGNORECASE and _TURNING.flags & re.IGNORECASE
    return {"counted": _COUNTED.pattern, "turning": _TURNING.pattern,
            "margin_seconds": MARGIN_SECONDS, "moving_speed": MOVING_SPEED,
            "stopped_share": STOPPED_SHARE, "smooth_seconds": SMOOTH_SECONDS,
            "steady_share": STEADY_SHARE, "max_turn_rate": MAX_TURN_RATE,
            "min_straightness": MIN_STRAIGHTNESS, "moving_share": MOVING_SHARE,
            "min_steps": MIN_STEPS,
            "max_warp": MAX_WARP, "warp_cost": WARP_COST}
