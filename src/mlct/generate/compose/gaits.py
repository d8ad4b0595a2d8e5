"""generate()'s gaits that keep going: a one-action gait asked for clearly longer than its
natural length, or past the window, made again as takes chained into one continuing motion
(keep_going.py holds how; this, when and with which samples)."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from mlct.generate.compose.lengths import MIN_PART_SECONDS, too_long
from mlct.generate.compose.reading import LOG
from mlct.generate.seeds import Sampling
from mlct.generate.output.generated import GeneratedMotion
from mlct.generate.seeds import MAX_SEED


def keep_going(gen: Any, out: list[GeneratedMotion | None], indices: Sequence[int],
               frames: Sequence[int], seeds: Sequence[int], how: Sampling) -> None:
    """A one-action gait asked for clearly longer than its natural length that stopped
    early, or asked past the window (made at the window's length so far), is made again as
    takes of its natural length chained into one continuing motion (keep_going.py); out[i]
    is replaced in place. A prompt past the window that is no gait raises the window's
    error. Needs the duration model."""
    from mlct.generate.compose.batch_plan import Sample, samples_ahead
    from mlct.generate.compose.keep_going import names_an_end, takes_needed
    from mlct.generate.compose.long_motion import blend_frames
    from mlct.generate.compose.timing import duration_vectors

    if gen.durations is None or not gen.keep_going:
        return
    fps = gen.skeleton.fps
    for i in indices:  # past the window (made at its length so far) only a gait goes on
        if frames[i] > gen.max_frames and names_an_end(out[i].text):
            raise too_long(gen, frames[i], text=out[i].text)
    todo = [i for i in indices if not names_an_end(out[i].text)
            and frames[i] / fps >= MIN_PART_SECONDS]
    if not todo:
        return
    vectors = duration_vectors(gen, [out[i].text for i in todo])
    natural = [gen.durations.clip_seconds(vector[None]) for vector in vectors]
    blend = blend_frames(fps)
    # every prompt's first takes in a few large batches (batch_plan.py)
    ahead = []
    for i, seconds in zip(todo, natural):
        needed = takes_needed(out[i].joints, frames[i], gen.max_frames, seconds, blend,
                              gen.skeleton)
        if needed is not None:
            ahead += [Sample(out[i].text, needed[1], (seeds[i] + k) % (MAX_SEED + 1))
                      for k in range(needed[0])]
    with samples_ahead(gen, ahead, how):
        for i, seconds in zip(todo, natural):
            _keep_going_one(gen, out, i, frames[i], seconds, blend, seeds[i], how)


def _keep_going_one(gen: Any, out: list[GeneratedMotion | None], i: int, frames: int,
                    natural_seconds: float, blend: int, seed: int, how: Sampling) -> None:
    """keep_going for out[i]."""
    from mlct.generate.compose.keep_going import continue_gait
    from mlct.generate.compose.long_motion import LongMotion

    fps = gen.skeleton.fps
    motion = out[i]

    def takes(count: int, take: int) -> list[np.ndarray]:
        made = gen.generate([motion.text] * count, lengths=take, nfe=how.steps,
                            seed=[(seed + k) % (MAX_SEED + 1) for k in range(count)],
                            guidance=how.guidance, split_actions=False,
                            candidates=how.candidates)
        return [m.joints for m in made]

    kept = continue_gait(motion.joints, frames, gen.max_frames, natural_seconds, blend,
                         gen.skeleton, takes)
    if kept is None:
        if frames > gen.max_frames:  # no gait, or its takes fell short
            raise too_long(gen, frames, text=motion.text)
        return  # as the model made it
    LOG.info("%r kept going: %d takes of %.1f s chained into %.1f s (--no-keep-going: "
             "as the model made it)", motion.text, len(kept.takes),
             kept.take_frames / fps, frames / fps)
    # a LongMotion, as a chain of prompts is: its seams and the takes as made; its
    # features derived from the joints when read (generated.py)
    out[i] = LongMotion(motion.text, None, kept.joints.astype(np.float32), fps,
                        gen.skeleton.name, seed, seams=tuple(kept.seams),
                        texts=(motion.text,) * len(kept.takes), blend=blend,
                        segments=tuple(kept.takes))
