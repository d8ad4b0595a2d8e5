"""SMPL / AMASS parameters (.npz): the shared rotation fit as SMPL+H axis-angle poses.

HumanML3D's 22 joints are the SMPL body's first 22, so a motion fitted on the `smpl` preset
(rigs.py: SMPL's joint names and its T-pose, arms out) is a sequence of SMPL pose parameters. The
file follows AMASS, whose loaders (human_body_prior's BodyModel, smplx, the HumanML3D pipeline)
read it as is; no SMPL model file is needed to write it:

- `poses` (T, 156): SMPL+H axis-angle, 52 joints x 3: [0:3] the global orientation, [3:66]
  the 21 body joints in SMPL order, [66:156] the hands (zero: mlct has no fingers). An SMPL
  (24-joint) reader takes poses[:, :66] and two zero hand joints;
- `smpl_poses` (T, 72): the same as plain SMPL's 24 joints x 3 (the 22 body joints, then the
  two hand joints, zero), the layout of SMPL-only files such as AIST++'s;
- `trans` (T, 3): the pelvis position. An SMPL body puts its pelvis at J0 + trans, J0 being its
  template's pelvis joint for the given betas (a model file's, so not here): subtract
  `body_model(betas=...).joints[0, 0]` to place the body exactly;
- `betas` (16,) zeros (the mean shape), `dmpls` (T, 8) zeros, `gender` "neutral",
  `mocap_framerate` (AMASS's key) and `mocap_frame_rate` (its newer spelling);
- `root_orient` (T, 3), `pose_body` (T, 63), `pose_hand` (T, 90): the same values under the
  keys of AMASS's newer releases;
- `rest_offsets` (22, 3): the bone offsets of the rest pose the poses are relative to (mlct's
  fit: the motion's bone lengths along SMPL's T-pose), in the body's own frame, so that the file
  alone rebuilds the fitted joints (`smpl_joints`).

Axes: AMASS is z up. The HumanML3D processing turns AMASS's (x, y, z) into (-x, z, y) (its
trans_matrix, then x negated); the writer applies the inverse, a proper rotation, to the root's
orientation and to `trans`, so that a motion goes through that processing back to itself.
"""

from __future__ import annotations

import io
import os

import numpy as np

from mlct.errors import MlctError
from mlct.io import write_bytes
from mlct.motion.rotations import matrix_to_quat, quat_to_rotvec, rotvec_to_matrix
from mlct.motion.rigfit import RigFit, fit_rig, forward
from mlct.motion.rigs import get_rig
from mlct.motion.skeleton import HUMANML3D, Skeleton

# mlct's frame (y up, facing +Z) -> AMASS's world (z up): (x, y, z) -> (-x, z, y).
TO_AMASS = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
SMPLH_JOINTS = 52
BODY_JOINTS = 22
N_BETAS, N_DMPLS = 16, 8


def fit_for_smpl(joints: np.ndarray, skeleton: Skeleton, fps: float) -> RigFit:
    """The rig fit on SMPL's T-pose, in metres, in mlct's frame."""
    if skeleton.name != HUMANML3D.name:
        raise MlctError(f"SMPL parameters need the humanml3d (SMPL) skeleton, not "
                        f"{skeleton.name}")
    smpl = get_rig("smpl", skeleton)
    assert smpl is not None
    return fit_rig(joints, skeleton, smpl.rest_directions, fps=fps)


def smpl_params(joints: np.ndarray, skeleton: Skeleton, fps: float) -> dict[str, np.ndarray]:
    """The AMASS-style arrays of (T, 22, 3) humanml3d joints at `fps` (module doc)."""
    rate = float(fps) if isinstance(fps, (int, float)) else float("nan")
    if not (np.isfinite(rate) and rate > 0):
        raise MlctError(f"SMPL export needs a positive frame rate, got {fps!r}")
    fit = fit_for_smpl(joints, skeleton, rate)
    n_frames = len(fit.root)
    local = fit.local.copy()
    local[:, 0] = TO_AMASS @ local[:, 0]  # the global orientation, into AMASS's world
    rotvec = quat_to_rotvec(matrix_to_quat(local))  # (T, 22, 3)
    poses = np.zeros((n_frames, SMPLH_JOINTS * 3))
    poses[:, :BODY_JOINTS * 3] = rotvec.reshape(n_frames, -1)
    return {
        "poses": poses, "trans": fit.root @ TO_AMASS.T, "betas": np.zeros(N_BETAS),
        "dmpls": np.zeros((n_frames, N_DMPLS)), "gender": np.array("neutral"),
        "mocap_framerate": np.array(rate), "mocap_frame_rate": np.array(rate),
        "smpl_poses": np.concatenate([poses[:, :BODY_JOINTS * 3], np.zeros((n_frames, 6))], 1),
        "root_orient": poses[:, :3], "pose_body": poses[:, 3:66], "pose_hand": poses[:, 66:],
        "rest_offsets": fit.offsets,
    }


def smpl_npz_bytes(joints: np.ndarray, skeleton: Skeleton, fps: float) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **smpl_params(joints, skeleton, fps))
    return buffer.getvalue()


def write_smpl_npz(path: str | os.PathLike, joints: np.ndarray, skeleton: Skeleton,
                   fps: float) -> None:
    """Write the AMASS-style .npz of (T, 22, 3) humanml3d joints, atomically (module doc)."""
    write_bytes(path, smpl_npz_bytes(joints, skeleton, fps))


def smpl_joints(params) -> np.ndarray:
    """(T, 22, 3) joints, in AMASS's world, that an .npz's `poses`, `trans` and `rest_offsets`
    give by forward kinematics on the SMPL tree (what a body model does with its own offsets)."""
    poses = np.asarray(params["poses"], dtype=np.float64)
    n_frames = len(poses)
    rotvec = poses[:, :BODY_JOINTS * 3].reshape(n_frames, BODY_JOINTS, 3)
    local = rotvec_to_matrix(rotvec)  # (T, 22, 3, 3)
    parents = HUMANML3D.parents
    order = tuple(range(BODY_JOINTS))  # SMPL lists every parent before its children
    positions, _ = forward(parents, order, np.asarray(params["rest_offsets"], np.float64),
                           np.asarray(params["trans"], np.float64), local)
    return positions
