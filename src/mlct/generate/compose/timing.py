"""A prompt's seconds from its text (the duration model, durations.py) as generate() uses them:
a clip's default length, "auto" seconds, a sequence's parts' shares."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.generate.compose.durations import DurationModel, split_frames
from mlct.generate.compose.lengths import DEFAULT_SECONDS, MIN_PART_SECONDS, wants_auto
from mlct.generate.compose.reading import parts_as_made


def duration_model(gen: Any) -> DurationModel:
    """The model's duration model; MlctError when it has none (seconds "auto")."""
    if gen.durations is None:
        raise MlctError("this model has no duration model to take seconds from the text "
                        "(make one with `mlct train durations`); give the seconds")
    return gen.durations


def duration_vectors(gen: Any, texts: Sequence[str]) -> np.ndarray:
    """(B, c) the vectors the duration model reads: the text as the network samples from it
    (sampling_text), so that a prompt worded unlike every caption is timed as the motion
    it is pulled towards is made. Read raw, "walk around in a circle going anticlockwise"
    got 4.1 s and its circle was cut off at the 5 s floor (~250 degrees); pulled, 6.9 s
    (docs/model_card.md)."""
    vectors = gen.sampling_text(gen.encode_text(list(texts)))
    if isinstance(vectors, np.ndarray):  # the onnx backend's
        return vectors.astype(np.float32, copy=False)
    return vectors.float().cpu().numpy()


def default_seconds(gen: Any, texts: Sequence[str], split_actions: bool = True) -> list[float]:
    """Each text's length when neither the caller nor the prompt gives one: DEFAULT_SECONDS,
    or longer when the duration model says its actions take longer (a circle walk, a stretch,
    two actions in turn), up to the window. Never shorter: a short action is followed by
    standing, as before. Against a flat 5 s on the hand-written prompts (5 seeds): held-out 2
    0.828 -> 0.874, the other sets the same or better (docs/model_card.md)."""
    flat = min(DEFAULT_SECONDS, gen.max_frames / gen.skeleton.fps)  # a short window's
    if gen.durations is None:
        return [flat] * len(texts)
    return [max(flat, s) for s in auto_seconds(gen, texts, "auto", split_actions)]


def auto_seconds(gen: Any, texts: Sequence[str], seconds: Any = "auto",
                 split_actions: bool = True) -> list[float]:
    """Each text's seconds, those given as "auto" predicted from the text as its parts
    would be made (DurationModel.clip_seconds: an arm action done during another lasts as
    long as the other), within MIN_PART_SECONDS and the model's window."""
    given = [seconds] * len(texts) if isinstance(seconds, str) else list(seconds)
    if len(given) != len(texts):
        raise MlctError(f"{len(given)} seconds for {len(texts)} texts")
    durations = duration_model(gen)
    plans = {}  # text index -> its parts, as generate() would make them
    for i, (text, value) in enumerate(zip(texts, given)):
        if wants_auto(value):
            plans[i] = parts_as_made(text, split_actions)[0]
    parts = [p for plan in plans.values() for p in plan]
    vectors = duration_vectors(gen, parts) if parts else None
    longest = gen.max_frames / gen.skeleton.fps
    start = 0
    for i, plan in plans.items():  # one text-encoder call for all of them
        clip = durations.clip_seconds(vectors[start:start + len(plan)])
        given[i] = float(np.clip(clip, MIN_PART_SECONDS, longest))
        start += len(plan)
    return given


def long_part_seconds(gen: Any, prompts: Sequence[str], seconds: Sequence[Any]) -> list[Any]:
    """The seconds of a long motion's prompts (generate_long), those given as "auto" each
    prompt's share of the whole as the duration model times a sequence's parts
    (DurationModel.part_seconds), at least MIN_PART_SECONDS."""
    if not wants_auto(list(seconds)):
        return list(seconds)
    natural = duration_model(gen).part_seconds(duration_vectors(gen, prompts))
    return [max(float(n), MIN_PART_SECONDS) if wants_auto(s) else s
            for s, n in zip(seconds, natural)]


def part_frames(gen: Any, parts: Sequence[str], frames: int) -> list[int]:
    """Each part's frames of a sequence of `frames`: its share by how long its action takes
    and its place in the sequence (durations.py; equal when the model has no duration
    model), at least MIN_PART_SECONDS where the total allows."""
    weights = (gen.durations.part_weights(duration_vectors(gen, parts),
                                          frames / gen.skeleton.fps, MIN_PART_SECONDS)
               if gen.durations else np.ones(len(parts)))
    return split_frames(weights, frames, gen.frames_for(MIN_PART_SECONDS))
