"""The Unitree G1 (29 degrees of freedom) as a kinematic table: bodies, joints, axes, limits.

Facts transcribed from Unitree's MuJoCo model `unitree_robots/g1/g1_29dof.xml` in
github.com/unitreerobotics/unitree_mujoco (commit ab03eec5 of that file), which is distributed
under the BSD 3-Clause License, Copyright (c) 2016-2024 HangZhou YuShu TECHNOLOGY CO.,LTD.
("Unitree Robotics"). Only the numbers that forward kinematics needs are copied (body offsets
and orientations, joint axes and ranges, the foot's contact spheres); meshes, inertias and
actuators are not. Units: metres and radians; MuJoCo's frame: z up, the robot faces +x, its
left is +y. Quaternions are MuJoCo's (w, x, y, z).

The joint order is the MJCF's (depth-first through the body tree), which is the order of
MuJoCo's qpos after the free joint's 7 numbers and of Unitree's motor indices.
"""

from __future__ import annotations

from typing import NamedTuple

NAME = "g1"
SOURCE = ("unitree_robots/g1/g1_29dof.xml, github.com/unitreerobotics/unitree_mujoco "
          "(BSD-3-Clause, Unitree Robotics)")


class Body(NamedTuple):
    name: str
    parent: str | None
    pos: tuple[float, float, float]  # in the parent's frame
    quat: tuple[float, float, float, float]  # w, x, y, z: the body frame in the parent's
    joint: str | None  # the hinge at the body's origin (None: the free-floating pelvis)
    axis: int  # 0, 1, 2: the hinge turns about the body's own x, y or z
    lower: float  # rad
    upper: float


_I = (1.0, 0.0, 0.0, 0.0)
_HIP_ROLL = (0.996179, 0.0, -0.0873386, 0.0)  # the thigh's 10 degree pitch, undone at the knee
_KNEE = (0.996179, 0.0, 0.0873386, 0.0)
X, Y, Z = 0, 1, 2

BODIES: tuple[Body, ...] = (
    Body("pelvis", None, (0.0, 0.0, 0.793), _I, None, 0, 0.0, 0.0),
    Body("left_hip_pitch_link", "pelvis", (0.0, 0.064452, -0.1027), _I,
         "left_hip_pitch_joint", Y, -2.5307, 2.8798),
    Body("left_hip_roll_link", "left_hip_pitch_link", (0.0, 0.052, -0.030465), _HIP_ROLL,
         "left_hip_roll_joint", X, -0.5236, 2.9671),
    Body("left_hip_yaw_link", "left_hip_roll_link", (0.025001, 0.0, -0.12412), _I,
         "left_hip_yaw_joint", Z, -2.7576, 2.7576),
    Body("left_knee_link", "left_hip_yaw_link", (-0.078273, 0.0021489, -0.17734), _KNEE,
         "left_knee_joint", Y, -0.087267, 2.8798),
    Body("left_ankle_pitch_link", "left_knee_link", (0.0, -9.4445e-05, -0.30001), _I,
         "left_ankle_pitch_joint", Y, -0.87267, 0.5236),
    Body("left_ankle_roll_link", "left_ankle_pitch_link", (0.0, 0.0, -0.017558), _I,
         "left_ankle_roll_joint", X, -0.2618, 0.2618),
    Body("right_hip_pitch_link", "pelvis", (0.0, -0.064452, -0.1027), _I,
         "right_hip_pitch_joint", Y, -2.5307, 2.8798),
    Body("right_hip_roll_link", "right_hip_pitch_link", (0.0, -0.052, -0.030465), _HIP_ROLL,
         "right_hip_roll_joint", X, -2.9671, 0.5236),
    Body("right_hip_yaw_link", "right_hip_roll_link", (0.025001, 0.0, -0.12412), _I,
         "right_hip_yaw_joint", Z, -2.7576, 2.7576),
    Body("right_knee_link", "right_hip_yaw_link", (-0.078273, -0.0021489, -0.17734), _KNEE,
         "right_knee_joint", Y, -0.087267, 2.8798),
    Body("right_ankle_pitch_link", "right_knee_link", (0.0, 9.4445e-05, -0.30001), _I,
         "right_ankle_pitch_joint", Y, -0.87267, 0.5236),
    Body("right_ankle_roll_link", "right_ankle_pitch_link", (0.0, 0.0, -0.017558), _I,
         "right_ankle_roll_joint", X, -0.2618, 0.2618),
    Body("waist_yaw_link", "pelvis", (0.0, 0.0, 0.0), _I, "waist_yaw_joint", Z, -2.618, 2.618),
    Body("waist_roll_link", "waist_yaw_link", (-0.0039635, 0.0, 0.035), _I,
         "waist_roll_joint", X, -0.52, 0.52),
    Body("torso_link", "waist_roll_link", (0.0, 0.0, 0.019), _I,
         "waist_pitch_joint", Y, -0.52, 0.52),
    Body("left_shoulder_pitch_link", "torso_link", (0.0039563, 0.10022, 0.23778),
         (0.990264, 0.139201, 1.38722e-05, -9.86868e-05),
         "left_shoulder_pitch_joint", Y, -3.0892, 2.6704),
    Body("left_shoulder_roll_link", "left_shoulder_pitch_link", (0.0, 0.038, -0.013831),
         (0.990268, -0.139172, 0.0, 0.0), "left_shoulder_roll_joint", X, -1.5882, 2.2515),
    Body("left_shoulder_yaw_link", "left_shoulder_roll_link", (0.0, 0.00624, -0.1032), _I,
         "left_shoulder_yaw_joint", Z, -2.618, 2.618),
    Body("left_elbow_link", "left_shoulder_yaw_link", (0.015783, 0.0, -0.080518), _I,
         "left_elbow_joint", Y, -1.0472, 2.0944),
    Body("left_wrist_roll_link", "left_elbow_link", (0.1, 0.00188791, -0.01), _I,
         "left_wrist_roll_joint", X, -1.97222, 1.97222),
    Body("left_wrist_pitch_link", "left_wrist_roll_link", (0.038, 0.0, 0.0), _I,
         "left_wrist_pitch_joint", Y, -1.61443, 1.61443),
    Body("left_wrist_yaw_link", "left_wrist_pitch_link", (0.046, 0.0, 0.0), _I,
         "left_wrist_yaw_joint", Z, -1.61443, 1.61443),
    Body("right_shoulder_pitch_link", "torso_link", (0.0039563, -0.10021, 0.23778),
         (0.990264, -0.139201, 1.38722e-05, 9.86868e-05),
         "right_shoulder_pitch_joint", Y, -3.0892, 2.6704),
    Body("right_shoulder_roll_link", "right_shoulder_pitch_link", (0.0, -0.038, -0.013831),
         (0.990268, 0.139172, 0.0, 0.0), "right_shoulder_roll_joint", X, -2.2515, 1.5882),
    Body("right_shoulder_yaw_link", "right_shoulder_roll_link", (0.0, -0.00624, -0.1032), _I,
         "right_shoulder_yaw_joint", Z, -2.618, 2.618),
    Body("right_elbow_link", "right_shoulder_yaw_link", (0.015783, 0.0, -0.080518), _I,
         "right_elbow_joint", Y, -1.0472, 2.0944),
    Body("right_wrist_roll_link", "right_elbow_link", (0.1, -0.00188791, -0.01), _I,
         "right_wrist_roll_joint", X, -1.97222, 1.97222),
    Body("right_wrist_pitch_link", "right_wrist_roll_link", (0.038, 0.0, 0.0), _I,
         "right_wrist_pitch_joint", Y, -1.61443, 1.61443),
    Body("right_wrist_yaw_link", "right_wrist_pitch_link", (0.046, 0.0, 0.0), _I,
         "right_wrist_yaw_joint", Z, -1.61443, 1.61443),
)

JOINT_NAMES: tuple[str, ...] = tuple(b.joint for b in BODIES if b.joint is not None)

# The foot's four contact spheres (radius 5 mm) in the ankle roll link's frame: heel and toe
# corners. Their lowest points, 35 mm under the link's origin, are the sole.
SOLE_CORNERS = ((-0.05, 0.025, -0.03), (-0.05, -0.025, -0.03), (0.12, 0.03, -0.03),
                (0.12, -0.03, -0.03))
SOLE_RADIUS = 0.005
