"""Stage 1 as the pipeline uses it: a test motion reconstructed the way generate() composes one.

The motion suite's reconstructions (bench/quality.py motion --ae) are there to say where
quality is lost, stage 1 or stage 2: the best any stage 2 could reach is what the autoencoder
can give back. The bundled pipeline does
not ask the autoencoder for every motion whole (generate/compose/generator.py):

- a prompt that names actions in turn is made one action at a time, each part its own latent,
  and the parts are chained (long_motion.chain_segments) when each gets at least
  MIN_PART_SECONDS;
- an arm action done during locomotion ("walks while waving") is made as the locomotion, and
  the arm action alone, standing, whose arms are re-attached to the locomotion
  (control_fit.reattach, the body-part edit).

`pipeline_reconstruction` mirrors that on a labelled test motion, with the truth's own action
boundaries (the best case of the pipeline's split): each action's stretch is reconstructed alone
and the stretches chained with the pipeline's blend; for a concurrent arm action, the truth's
arms re-attached to a standing body (its first frame, held) are reconstructed alone and
re-attached to the reconstructed locomotion. Everything else is reconstructed whole, as the
plain (b) does. The autoencoder is a callable, features -> joints, so the composition is tested
without one (tests/test_pipeline_recon.py).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np

from mlct.generate.control.schema import part_joints
from mlct.generate.control.fit import reattach
from mlct.generate.compose.long_motion import blend_frames, chain_segments
from mlct.generate.compose.lengths import MIN_PART_SECONDS
from mlct.motion.features import features_to_joints, joints_to_features
from mlct.motion.skeleton import Skeleton

Reconstruct = Callable[[np.ndarray], np.ndarray]  # features (T, D) -> joints (T, J, 3)


def action_cuts(label: Mapping[str, Any], frames: int, fps: float, blend: int) -> list[int]:
    """The frames where one action hands over to the next: halfway between the end of one and
    the start of the next (their windows overlap by a short transition in the benchmark), kept
    where the stretch after the last cut still holds the blend and a frame more."""
    actions = label["actions"]
    cuts = []
    for before, after in zip(actions, actions[1:]):
        cut = int(round(fps * (float(before["end"]) + float(after["start"])) / 2))
        cuts.append(min(max(cut, 1), frames - blend - 1))
    return cuts


def reconstruct_sequence(features: np.ndarray, cuts: list[int], blend: int,
                         reconstruct: Reconstruct, skeleton: Skeleton) -> np.ndarray:
    """Each stretch between cuts reconstructed alone (every stretch but the last runs `blend`
    frames on, as generate_long makes its parts) and chained as generate_long chains them."""
    bounds = [0, *cuts, len(features)]
    stretches = list(zip(bounds, bounds[1:]))
    parts = [reconstruct(features[start:end + (blend if k + 1 < len(stretches) else 0)])
             for k, (start, end) in enumerate(stretches)]
    joints, _ = chain_segments(parts, blend, skeleton)
    return joints


def arms_over_standing(joints: np.ndarray, arms: tuple[int, ...], skeleton: Skeleton
                       ) -> np.ndarray:
    """The motion's arms on a body that stands still in its first frame's pose: what the
    pipeline makes from the arm action's text alone before re-attaching it."""
    still = np.repeat(joints[:1], len(joints), axis=0)
    return reattach(joints, still, arms, skeleton)


def as_features(joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """joints_to_features keeping the frame count (it returns one frame fewer)."""
    padded = np.concatenate([joints, joints[-1:]], axis=0)
    return joints_to_features(padded.astype(np.float64), skeleton).features


def pipeline_reconstruction(features: np.ndarray, label: Mapping[str, Any],
                            reconstruct: Reconstruct, skeleton: Skeleton,
                            truth: np.ndarray | None = None) -> np.ndarray:
    """The joints (T, J, 3) of `features` (real units) reconstructed as the pipeline would
    compose the motion its label describes (module docstring); truth: the motion's joints
    (features_to_joints(features)), when the caller has them already."""
    fps = skeleton.fps
    frames = len(features)
    actions = label["actions"]
    blend = blend_frames(fps)
    if len(actions) > 1 and frames // len(actions) >= round(MIN_PART_SECONDS * fps):
        body = reconstruct_sequence(features, action_cuts(label, frames, fps, blend), blend,
                                    reconstruct, skeleton)
    else:
        body = reconstruct(features)
    if not label.get("concurrent"):
        return body
    if truth is None:
        truth = features_to_joints(features)
    arms = part_joints("arms", skeleton)
    made = reconstruct(as_features(arms_over_standing(truth, arms, skeleton), skeleton))
    return reattach(made, body, arms, skeleton)
