"""A prompt made of parts: actions in turn, chained into one motion (long_motion.py), and an
arm action done during another, its arms re-attached to the body (control/fit.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mlct.generate.compose.timing import part_frames
from mlct.generate.seeds import Sampling
from mlct.generate.output.generated import GeneratedMotion


def chained(gen: Any, text: str, parts: list[str], frames: int, seed: int, how: Sampling
            ) -> GeneratedMotion:
    """One motion of `frames` doing parts[k] in turn, under the whole text."""
    from mlct.generate.compose.long_motion import generate_long

    fps = gen.skeleton.fps
    made = generate_long(gen, parts, [n / fps for n in part_frames(gen, parts, frames)],
                         nfe=how.steps, seed=seed, guidance=how.guidance,
                         candidates=how.candidates)
    return made.renamed(text)


def concurrent(gen: Any, text: str, body: str, arms: str, frames: int, seed: int,
               how: Sampling) -> GeneratedMotion:
    """An arm action done during another: the body made from `body` (split into its actions
    as any prompt), the arm action made from `arms` alone, standing, each the best of the
    candidates; then the arms' bones re-attached to the body, turned into its facing
    (control.fit.reattach, the body-part edit's last step). Not the edit control itself:
    its guidance pulls the arm sample toward the body, which reattach replaces anyway, and
    its candidates are chosen by that, not by the critic; on the benchmark's concurrent
    test captions the arms passed 0.843 that way, 0.899 this way (docs/training.md)."""
    # imported here: control.fit needs scipy, which a cold start must not load
    from mlct.generate.control.fit import reattach
    from mlct.generate.control.schema import part_joints

    skeleton = gen.skeleton
    made = gen.generate(body, lengths=frames, nfe=how.steps, seed=seed,
                        guidance=how.guidance, candidates=how.candidates)[0]
    standing = gen.generate(arms, lengths=frames, nfe=how.steps, seed=seed,
                            guidance=how.guidance, candidates=how.candidates)[0]
    joints = reattach(standing.joints.astype(np.float64), made.joints.astype(np.float64),
                      part_joints("arms", skeleton), skeleton)
    return GeneratedMotion(text, None, joints.astype(np.float32), skeleton.fps,
                           skeleton.name, seed)  # features derived when read
