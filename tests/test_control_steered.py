"""Steering inside the consistency steps (generate/control/steered.py): the bundled model's
encoder, the projection, and the correction after it."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

FRAMES = 120


@pytest.fixture(scope="module")
def pipe():
    import mlct

    return mlct.load()


def along_z(speed: float, frames: int = FRAMES):
    from mlct.generate.control.schema import Control

    at = np.unique(np.r_[np.arange(0, frames, 20), frames - 1])
    return Control(path=np.stack([np.zeros(len(at)), speed * at / 20.0], axis=1), path_frames=at)


def test_a_motion_of_the_model_encoded_and_decoded_stays_near_itself(pipe) -> None:
    from mlct.generate.control import steered

    z = pipe.sample_latents(pipe.encode_text(["a person walks forward"]), seed=[0])
    made = steered.decode(pipe, z, FRAMES)
    again = steered.decode(pipe, steered.encode(pipe, made), FRAMES)
    assert again.shape == made.shape == (FRAMES, 22, 3)
    # the body within a few cm; its root, integrated from velocities, drifts more
    body = lambda j: j - j[:, :1]  # noqa: E731
    assert np.abs(body(again) - body(made)).mean() < 0.02
    assert np.linalg.norm(again[-1, 0, [0, 2]] - made[-1, 0, [0, 2]]) < 0.3


def test_steering_no_step_is_the_seed_s_own_sample(pipe) -> None:
    from mlct.generate.control.controlled import ControlMethod, controlled_motion

    control = along_z(0.7).check(FRAMES, pipe.skeleton)
    text = "a person walks forward"
    off = controlled_motion(pipe, text, FRAMES, control, None, 3,
                            ControlMethod(pace=False, steer=True, steered_steps=0))
    plain = controlled_motion(pipe, text, FRAMES, control, None, 3,
                              ControlMethod(pace=False, candidates=1))
    np.testing.assert_allclose(off.before, plain.before, atol=1e-4)


def test_steered_motion_moves_and_the_correction_makes_the_path_exact(pipe) -> None:
    from mlct.generate.control.controlled import ControlMethod, controlled_motion

    control = along_z(0.7).check(FRAMES, pipe.skeleton)
    text = "a person walks forward"
    steered = controlled_motion(pipe, text, FRAMES, control, None, 3,
                                ControlMethod(pace=False, steer=True))
    plain = controlled_motion(pipe, text, FRAMES, control, None, 3,
                              ControlMethod(pace=False, candidates=1))
    assert np.abs(steered.before - plain.before).max() > 0.01  # the projection moved it
    at = control.path_frames
    final = np.linalg.norm(steered.motion.joints[at, 0][:, [0, 2]] - control.path, axis=1)
    assert final.max() < 0.01
