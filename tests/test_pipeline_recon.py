"""Stage 1 as the pipeline uses it (mlct/eval/pipeline_recon.py): the composition itself must
give the truth back when the autoencoder is perfect, call the autoencoder once per stretch, and
carry a concurrent arm action through the standing body only."""

from __future__ import annotations

import numpy as np
import pytest

from mlct.data.synth.build import make_motion
from mlct.eval.pipeline_recon import (action_cuts, arms_over_standing, as_features,
                                      pipeline_reconstruction)
from mlct.eval.readouts import evaluate_label
from mlct.generate.control.schema import part_joints
from mlct.generate.compose.long_motion import BLEND_SECONDS
from mlct.motion.features import features_to_joints
from mlct.motion.skeleton import HUMANML3D


def _motion(kind: str):
    """The first motion of the seed-0 benchmark that is of this kind."""
    for index in range(200):
        motion = make_motion(index, seed=0, skeleton=HUMANML3D)
        label = motion.label
        found = ("concurrent" if label["concurrent"] else
                 "sequence" if len(label["actions"]) > 1 else "one")
        if found == kind:
            return motion
    raise AssertionError(f"no {kind} motion in the first 200")


class Recorder:
    """A perfect autoencoder that notes the length of each clip it is given."""

    def __init__(self) -> None:
        self.lengths: list[int] = []

    def __call__(self, features: np.ndarray) -> np.ndarray:
        self.lengths.append(len(features))
        return features_to_joints(features)


@pytest.mark.parametrize("kind", ["one", "sequence", "concurrent"])
def test_a_perfect_autoencoder_gives_the_truth_back(kind):
    motion = _motion(kind)
    truth = features_to_joints(motion.features)
    made = pipeline_reconstruction(motion.features, motion.label, Recorder(), HUMANML3D)
    assert made.shape == truth.shape
    assert np.abs(made - truth).max() < 1e-3  # metres
    assert all(passed for _, passed in evaluate_label(made, motion.label))


def test_a_sequence_is_reconstructed_one_action_at_a_time():
    motion = _motion("sequence")
    frames = len(motion.features)
    blend = round(BLEND_SECONDS * HUMANML3D.fps)
    cuts = action_cuts(motion.label, frames, HUMANML3D.fps, blend)
    assert len(cuts) == len(motion.label["actions"]) - 1
    recorder = Recorder()
    pipeline_reconstruction(motion.features, motion.label, recorder, HUMANML3D)
    bounds = [0, *cuts, frames]
    expected = [end - start + blend for start, end in zip(bounds, bounds[1:])]
    expected[-1] -= blend  # every stretch but the last runs on into the next one's blend
    assert recorder.lengths == expected


def test_the_cut_falls_between_the_actions():
    label = {"actions": [{"start": 0.2, "end": 2.2}, {"start": 1.8, "end": 4.0}]}
    assert action_cuts(label, 100, 20.0, 15) == [40]
    # never so late that the last stretch cannot hold the blend
    late = {"actions": [{"start": 0.2, "end": 4.9}, {"start": 4.9, "end": 5.0}]}
    assert action_cuts(late, 100, 20.0, 15) == [84]


def test_a_concurrent_arm_action_goes_through_a_standing_body():
    motion = _motion("concurrent")
    truth = features_to_joints(motion.features)
    arms = part_joints("arms", HUMANML3D)
    standing = arms_over_standing(truth, arms, HUMANML3D)
    legs = [j for j in range(HUMANML3D.n_joints) if j not in arms]
    assert np.abs(standing[:, legs] - truth[:1, legs]).max() < 1e-9  # the body holds still
    assert np.abs(standing[:, arms] - standing[:1, arms]).max() > 0.1  # the arms move
    # the features keep the frame count and give the standing body back
    again = features_to_joints(as_features(standing, HUMANML3D))
    assert again.shape == standing.shape
    recorder = Recorder()
    pipeline_reconstruction(motion.features, motion.label, recorder, HUMANML3D, truth)
    assert recorder.lengths == [len(truth), len(truth)]  # the locomotion, then the arms


def test_lost_arms_are_lost_in_the_composition_too():
    """An autoencoder that gives back the body but holds the arms still fails the arm action's
    checks: the composition adds nothing the autoencoder does not give."""
    motion = _motion("concurrent")
    arms = part_joints("arms", HUMANML3D)

    def no_arms(features: np.ndarray) -> np.ndarray:
        joints = features_to_joints(features)
        from mlct.generate.control.fit import reattach
        return reattach(np.repeat(joints[:1], len(joints), axis=0), joints, arms, HUMANML3D)

    made = pipeline_reconstruction(motion.features, motion.label, no_arms, HUMANML3D)
    results = evaluate_label(made, motion.label)
    assert not all(passed for name, passed in results if name.startswith("+:"))
