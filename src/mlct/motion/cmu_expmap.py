"""The CMU motion-prediction set's format (Li et al., "Convolutional Sequence to Sequence Model
for Human Dynamics", CVPR 2018; github.com/chaneyddtt/Convolutional-Sequence-to-Sequence-
Model-for-Human-Dynamics): CMU takes as comma-separated text, one frame a line, 117 values: the
root's position (3, CMU's ASF units, y up) and an exponential map (axis times angle, radians)
for each of the 38 joints of one CMU ASF skeleton, 120 frames a second.

The skeleton below is that repository's (forward_kinematics_cmu.py, `_some_variables`): the
parent of each joint and its offset from the parent at rest, in ASF units (that code scales
the offsets by 70 for its plots; the root positions are in the ASF units of the offsets, and
with them a walk covers ~1.2 m/s at 120 fps). Its forward kinematics, in row vectors:
x_j = o_j R_p + x_p and R_j = E_j R_p, E_j the rotation of joint j's exponential map and p its
parent; the root's E is its world rotation. A joint is named after the CMU bone that starts
there (as motion/asf_amc.py names them, so one joint map serves both), an end site after its
bone with "_end". This skeleton's thorax has zero length: the neck and the clavicles start
where the upper back ends.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from mlct.errors import MlctError
from mlct.motion.quaternion import rotvec_to_matrix

EXPMAP_FPS = 120.0
VALUES_PER_FRAME = 117  # 3 root position + 38 joints x 3

# (joint, parent, offset from the parent at rest in ASF units): the repository's parent list
# and offsets, joint by joint.
SKELETON: tuple[tuple[str, str | None, tuple[float, float, float]], ...] = (
    ("root", None, (0.0, 0.0, 0.0)),
    ("lhipjoint", "root", (0.0, 0.0, 0.0)),
    ("lfemur", "lhipjoint", (1.65674, -1.80282, 0.62477)),
    ("ltibia", "lfemur", (2.59720, -7.13576, 0.0)),
    ("lfoot", "ltibia", (2.49236, -6.84770, 0.0)),
    ("ltoes", "lfoot", (0.19704, -0.54136, 2.14581)),
    ("ltoes_end", "ltoes", (0.0, 0.0, 1.11249)),
    ("rhipjoint", "root", (0.0, 0.0, 0.0)),
    ("rfemur", "rhipjoint", (-1.61070, -1.80282, 0.62476)),
    ("rtibia", "rfemur", (-2.59502, -7.12977, 0.0)),
    ("rfoot", "rtibia", (-2.46780, -6.78024, 0.0)),
    ("rtoes", "rfoot", (-0.23024, -0.63258, 2.13368)),
    ("rtoes_end", "rtoes", (0.0, 0.0, 1.11569)),
    ("lowerback", "root", (0.0, 0.0, 0.0)),
    ("upperback", "lowerback", (0.01961, 2.05450, -0.14112)),
    ("thorax", "upperback", (0.01021, 2.06436, -0.05921)),
    ("lowerneck", "thorax", (0.0, 0.0, 0.0)),
    ("upperneck", "lowerneck", (0.00713, 1.56711, 0.14968)),
    ("head", "upperneck", (0.03429, 1.56041, -0.10006)),
    ("head_end", "head", (0.01305, 1.62560, -0.05265)),
    ("lclavicle", "thorax", (0.0, 0.0, 0.0)),
    ("lhumerus", "lclavicle", (3.54205, 0.90436, -0.17364)),
    ("lradius", "lhumerus", (4.86513, 0.0, 0.0)),
    ("lwrist", "lradius", (3.35554, 0.0, 0.0)),
    ("lhand", "lwrist", (0.0, 0.0, 0.0)),
    ("lfingers", "lhand", (0.66117, 0.0, 0.0)),
    ("lfingers_end", "lfingers", (0.53306, 0.0, 0.0)),
    ("lthumb", "lwrist", (0.0, 0.0, 0.0)),
    ("lthumb_end", "lthumb", (0.54120, 0.0, 0.54120)),
    ("rclavicle", "thorax", (0.0, 0.0, 0.0)),
    ("rhumerus", "rclavicle", (-3.49802, 0.75994, -0.32616)),
    ("rradius", "rhumerus", (-5.02649, 0.0, 0.0)),
    ("rwrist", "rradius", (-3.36431, 0.0, 0.0)),
    ("rhand", "rwrist", (0.0, 0.0, 0.0)),
    ("rfingers", "rhand", (-0.73041, 0.0, 0.0)),
    ("rfingers_end", "rfingers", (-0.58887, 0.0, 0.0)),
    ("rthumb", "rwrist", (0.0, 0.0, 0.0)),
    ("rthumb_end", "rthumb", (-0.59786, 0.0, 0.59786)),
)
JOINT_NAMES = tuple(name for name, _, _ in SKELETON)


@dataclass(frozen=True)
class ExpmapClip:
    joint_names: tuple[str, ...]
    positions: np.ndarray  # (T, 38, 3) world positions in ASF units, y up
    fps: float


def forward_kinematics(frames: np.ndarray) -> np.ndarray:
    """(T, 117) frames -> (T, 38, 3) joint positions (module doc)."""
    rotations = rotvec_to_matrix(torch.from_numpy(
        frames[:, 3:].reshape(len(frames), len(SKELETON), 3).astype(np.float64))).numpy()
    index = {name: j for j, name in enumerate(JOINT_NAMES)}
    world = np.empty((len(frames), len(SKELETON), 3, 3))  # row-vector rotations R_j
    positions = np.empty((len(frames), len(SKELETON), 3))
    for j, (_, parent, offset) in enumerate(SKELETON):
        if parent is None:
            world[:, j] = rotations[:, j]
            positions[:, j] = frames[:, :3] + np.asarray(offset)
            continue
        p = index[parent]
        world[:, j] = rotations[:, j] @ world[:, p]  # R_j = E_j R_p
        positions[:, j] = np.einsum("i,tij->tj", np.asarray(offset), world[:, p]) \
            + positions[:, p]  # x_j = o_j R_p + x_p
    return positions


def read_expmap(path: str | os.PathLike) -> ExpmapClip:
    """One sequence file of the set as world joint positions at 120 fps."""
    path = Path(path)
    try:
        frames = np.loadtxt(path, delimiter=",", ndmin=2, dtype=np.float64)
    except ValueError as error:
        raise MlctError(f"{path}: not comma-separated numbers ({error})") from None
    if frames.size == 0:
        raise MlctError(f"{path}: no frames")
    if frames.shape[1] != VALUES_PER_FRAME:
        raise MlctError(f"{path}: {frames.shape[1]} values a frame, expected "
                        f"{VALUES_PER_FRAME} (a root position and 38 exponential maps)")
    if not np.isfinite(frames).all():
        raise MlctError(f"{path}: the motion contains NaN or inf values")
    return ExpmapClip(joint_names=JOINT_NAMES, positions=forward_kinematics(frames),
                      fps=EXPMAP_FPS)
