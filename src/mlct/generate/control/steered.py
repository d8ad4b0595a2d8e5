"""Controls met inside the consistency steps by projection through the autoencoder: at each
steered step the clean latent x0 is decoded, the decoded motion is fitted to the controls in
motion space (`fit`: for a path the pace's re-timing and laying along it, then the correction's
fits; pace.py, fit.py) and x0 is moved by what the encoder makes of that fit,

    x0 <- x0 + E(fit(D(x0))) - E(D(x0))

(the difference of two encodings, so that what E o D does not give back of x0 stays); the
sampler re-noises the moved x0 for the next step, and the last step's x0 is the result's
latent. The body the decoder draws is then the model's, made for the controls, and the
correction (controlled.project) is left the last small fix.

Measured and not the default (`ControlMethod(pace=False, steer=True)`, bench/control.py
--speeds, docs/control.md): the encoder, trained on the data's motions, gives back a motion
re-timed to another pace, or started at full speed, as one that hardly moves or drifts (a paced
jog at 2x its speed encoded and decoded covers almost none of its path; a paced walk at its own
pace ends 0.5 m short of it), so each projection pulls the motion off the path rather than on
it, and the steps re-noise what it moved. PyTorch: the encoder runs as a torch module from the
bundle's `ae_encoder` weights (the ONNX graphs have no encoder; exporting one bought nothing
to export), on any backend's decoder and denoiser.
"""

from __future__ import annotations

import weakref
from typing import Any, Callable

import numpy as np
import torch
from torch import Tensor

from mlct.errors import MlctError
from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
from mlct.motion.features import joints_to_features
from mlct.motion.joints import features_to_joints
from mlct.nn.build import build_autoencoder

# compose.generator.MotionGenerator: named, not imported (a cycle)
MotionGenerator = Any
Fit = Callable[[np.ndarray], np.ndarray]  # (T, J, 3) decoded joints -> the same, fitted

_ENCODERS: "weakref.WeakKeyDictionary[Any, tuple[Any, Tensor, Tensor]]" = \
    weakref.WeakKeyDictionary()


def encoder_of(pipe: MotionGenerator) -> tuple[Any, Tensor, Tensor]:
    """The model's autoencoder as a torch module with its encoder's weights (from the bundle
    the generator was loaded from), and the features' mean and std; one-line MlctError when
    the bundle ships no encoder."""
    if pipe not in _ENCODERS:
        model_dir = pipe.meta.get("model_dir")
        if not model_dir:
            raise MlctError("steering needs the model's autoencoder encoder, which a model "
                            "not loaded from a directory does not have")
        meta, tensors = read_bundle(model_dir)
        ae = build_autoencoder(pipe.config, meta["feature_dim"])
        ae.load_state_dict(bundle_autoencoder_state(tensors, model_dir))
        _ENCODERS[pipe] = (ae.eval().requires_grad_(False), tensors["norm.mean"].float(),
                           tensors["norm.std"].float())
    return _ENCODERS[pipe]


def encode(pipe: MotionGenerator, joints: np.ndarray) -> Tensor:
    """(T, J, 3) joints -> (1, n, d) stage-2 latent (times the schedule's latent scale), the
    motion placed as the data's are (first frame at the origin, facing +Z)."""
    ae, mean, std = encoder_of(pipe)
    joints = np.asarray(joints, dtype=np.float64)
    feats = joints_to_features(np.concatenate([joints, joints[-1:]]), pipe.skeleton).features
    x = ((torch.as_tensor(feats) - mean) / std).float()[None]  # (1, T, D)
    with torch.no_grad():
        z = ae.encode(x, torch.tensor([len(feats)])).z
    return z * pipe.config.schedule.latent_scale


def decode(pipe: MotionGenerator, z: Tensor, frames: int) -> np.ndarray:
    """(1, n, d) stage-2 latent -> (T, J, 3) joints, by the generator's own decoder."""
    return features_to_joints(pipe.decode(z, [frames])[0]).astype(np.float64)


def steered_latent(pipe: MotionGenerator, text: str, frames: int, seed: int, nfe: int | None,
                   fit: Fit, steered_steps: int) -> Tensor:
    """(1, n, d): the seed's latent for `text`, its last `steered_steps` consistency steps'
    x0 each moved by the projection (module docstring)."""
    cond = torch.as_tensor(pipe.sampling_text(pipe.encode_text([text])))
    generators = [torch.Generator().manual_seed(int(seed) % (2**63))]
    steps = pipe.check_nfe(nfe)
    uncond = torch.as_tensor(pipe.encode_text([""])) if pipe.sampler.cfg else None
    calls = [0]

    def project(x0: Tensor) -> Tensor:
        calls[0] += 1
        if calls[0] <= steps - steered_steps:
            return x0
        made = decode(pipe, x0, frames)
        return x0 + (encode(pipe, fit(made)) - encode(pipe, made)).to(x0)

    x = pipe.sampler.noise((1, *pipe.ae.latent_shape), generators)
    with torch.no_grad():
        return pipe.sampler.sample(pipe.denoiser, x, cond, steps, generator=generators,
                                   uncond=uncond, guide=project)
