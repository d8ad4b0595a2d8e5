"""How long each motion of a generate() call is: frames from lengths or seconds, the model's
window, a gait's longer limit, a prompt's stated length, and the one-line errors."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.generate.compose.actions import split_actions
from mlct.generate.compose.prompts import stated_seconds

# The shortest share of a sequence's part: below it the blend (0.75 s) would be most of the part.
MIN_PART_SECONDS = 1.0
DEFAULT_SECONDS = 5.0  # a clip's length when neither the caller nor the prompt gives one
# A one-action gait keeps going past the model's window (compose/keep_going.py) up to this: a
# two-minute walk is 2,400 frames, ~70 takes, well under a second of sampling.
MAX_GAIT_SECONDS = 120.0


def frame_lengths(gen: Any, count: int, lengths: int | Sequence[int] | None,
                  seconds: float | Sequence[float] | None, longest: int | None = None
                  ) -> list[int]:
    """Frames per text; at most the model's window, or `longest` where generate() can
    keep a gait going past it."""
    longest = gen.max_frames if longest is None else longest
    if lengths is not None and seconds is not None:
        raise MlctError("give lengths (frames) or seconds, not both")
    if seconds is not None:
        secs = numbers(seconds, count, "seconds")
        for s in secs:
            if not np.isfinite(s) or s <= 0:
                raise MlctError(f"seconds must be a positive number, got {s}")
        lengths = [max(1, gen.frames_for(min(s, 1e6))) for s in secs]
    if lengths is None:
        lengths = [min(gen.max_frames, gen.frames_for(DEFAULT_SECONDS))] * count
    values = numbers(lengths, count, "lengths")
    if any(not np.isfinite(n) or n != int(n) for n in values):
        raise MlctError(f"lengths must be whole numbers of frames, got {lengths}")
    out = [int(n) for n in values]
    if len(out) != count:
        raise MlctError(f"{len(out)} lengths for {count} texts")
    for n in out:
        if not 1 <= n <= longest:
            raise too_long(gen, n, longest)
    return out


def longest_gait(gen: Any) -> int:
    """Frames a one-action gait may last: past the window when gaits keep going
    (compose/keep_going.py, which needs the duration model), else the window."""
    if gen.keep_going and gen.durations is not None:
        return gen.frames_for(MAX_GAIT_SECONDS)
    return gen.max_frames


def too_long(gen: Any, frames: int, longest: int | None = None, text: str | None = None
             ) -> MlctError:
    """The window's one-line error; `longest` > the window when a gait may go past it;
    `text`: the prompt (or a sequence's part) it is about."""
    window, fps = gen.max_frames, gen.skeleton.fps
    longer = ""
    if frames > window:
        longer = ("; for a longer motion give several prompts, one per part: they are "
                  "chained into one (mlct generate 'A' 'B' --seconds 5 5)")
        if longest is not None and longest > window:
            longer = (f"; a walk, a jog or another gait keeps going up to "
                      f"{longest / fps:g} s{longer}")
        elif gen.keep_going and gen.durations is not None:
            longer = (f" for this prompt: only a gait (a walk, a jog, a run...) keeps going "
                      f"past it{longer}")
    about = f"{text!r}: " if text else ""
    return MlctError(f"{about}length {frames} frames is outside 1..{window} "
                     f"({window / fps:.2f} s at {fps:g} fps){longer}")


def stated_lengths(texts: Sequence[str], split: bool = True
                   ) -> tuple[list[str], list[float | None]]:
    """Each prompt without a phrase that says how long ("walks forward for 20 seconds",
    prompts.stated_seconds), and the seconds it says (None: none). In a prompt of several actions
    the phrase is left where it is: whose duration it gives is not clear. generate() and the
    server's default length both read prompts this way."""
    clean, stated = [], []
    for text in texts:
        without, seconds = stated_seconds(text)
        if seconds is not None and split and len(split_actions(without)) > 1:
            seconds = None
        clean.append(without if seconds is not None else text)
        stated.append(seconds)
    return clean, stated


def is_scale(value: object) -> bool:
    """A finite real number >= 0 (a guidance scale), not a bool or a string."""
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, (bool, np.bool_)) and bool(np.isfinite(value))
            and value >= 0)


def numbers(value: object, count: int, name: str) -> list[float]:
    """A number for every item, or a list of them: floats; MlctError naming `name` otherwise."""
    def number(item: object) -> float:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, (int, float, np.number)):
            raise MlctError(f"{name} must be numbers, got {item!r}")
        return float(item)

    if isinstance(value, (list, tuple, np.ndarray)):
        return [number(item) for item in value]
    return [number(value)] * count


def wants_auto(seconds: Any) -> bool:
    """seconds="auto", or a list with an "auto" item (any case)."""
    if isinstance(seconds, str):
        if seconds.strip().lower() != "auto":
            raise MlctError(f'seconds must be a number, a list of them or "auto", '
                            f"got {seconds!r}")
        return True
    return isinstance(seconds, (list, tuple)) and any(
        isinstance(s, str) and wants_auto(s) for s in seconds)
