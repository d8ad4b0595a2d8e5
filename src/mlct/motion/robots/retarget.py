"""A HumanML3D joint motion (22 joints, y up, metres) retargeted to the Unitree G1's joint angles.

1. Axes: HumanML3D is y up and faces +z (the body's left is +x); MuJoCo is z up and the G1 faces
   +x (left +y): (x, y, z)_mujoco = (z, x, y)_human, a proper rotation.
2. Scale: every position times the ratio of leg lengths (the G1's hip-to-ankle over the motion's
   median thigh + shin), so the root's path and height shrink with the legs and the floor stays
   at z = 0.
3. Pelvis and waist, analytic: the pelvis turns with the hips (their left-right line, the world's
   up); the chest frame (shoulders' line, spine1 -> neck) relative to it is split into the waist's
   yaw, roll and pitch (its hinges' order, z x y), each clamped; chest pitch past the waist's
   range tilts the pelvis instead.
4. Legs: the ankle roll link's origin and the four sole corners follow the human ankle and the
   foot's yaw and pitch (ankle -> toe, less its rest pitch); where the motion's foot is planted
   (foot_lock.foot_contacts) the foot target is held flat on the floor at its mean place over the
   contact, fading in and out over a few frames. The knees follow lightly, the root's position
   is free with a weak pull to the hips: where the G1's legs cannot reach, the pelvis moves
   (mostly in height). Hip pitch / roll / yaw and knee start from the thigh and shin directions,
   then damped least squares on forward kinematics (chain.py) finishes, clamped to the limits.
5. Arms: the human's shoulder -> elbow and shoulder -> wrist vectors, in the chest's frame and
   scaled by the arm-length ratio, hang from the G1's shoulders in its torso's frame: always in
   reach whatever the waist did, except where the hand comes nearer the shoulder than the G1's
   elbow folds (about 10 cm). Shoulder pitch / roll / yaw and elbow start analytic from the
   upper-arm frame (starts.py; a few starts, the best kept per frame), then least squares; the
   wrists stay at zero (the joints carry no hand orientation).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mlct.errors import MlctError
from mlct.motion.foot_lock import correction, foot_contacts
from mlct.motion.robots import g1
from mlct.motion.robots.chain import Target, axis_rotation, matrix_to_quat, solve
from mlct.motion.robots.starts import CHAIN, arm_start, leg_start
from mlct.motion.skeleton import HUMANML3D, Skeleton, units_per_metre

BLEND = 3  # frames over which a held foot fades in and out (as foot_lock's)
FOOT_REST_PITCH = 0.32  # rad: a HumanML3D foot's ankle -> toe slope when flat (fallback)
SOLE = 0.035  # m: the ankle roll link's origin above the sole when the foot is flat
ITERATIONS = 30
# the elbow's pull against the hand's (1): enough to pick the elbow's side, small enough that
# an elbow the G1 cannot place with its hand costs the hand little
ELBOW_WEIGHT = 0.05
# analytic starts tried per arm: (rank of the splitting, with the motion's own elbow plane)
ARM_STARTS = ((0, True), (1, True), (2, True), (0, False), (1, False))
# m: an arm this near its targets (its weighted distance) tries no further start, and another
# start must bring it this much nearer for the frame to take it (fewer switches of solution)
ARM_SWITCH = 0.01
SIDES = ("left", "right")


@dataclass
class RobotMotion:
    """A retargeted motion: MuJoCo qpos per frame (free joint's xyz and wxyz, then the joint
    angles in joint_names' order) and what the solver aimed at."""

    robot: str
    fps: float
    joint_names: tuple[str, ...]
    qpos: np.ndarray  # (T, 7 + n)
    human: np.ndarray  # (T, 22, 3): the motion's joints in MuJoCo's frame, scaled
    scale: float  # G1 leg over the motion's leg
    contacts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), bool))  # (T, 2)
    targets: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (T, 3) world points

    @property
    def frames(self) -> int:
        return len(self.qpos)


def to_mujoco(points: np.ndarray) -> np.ndarray:
    """HumanML3D (y up, facing +z) positions as MuJoCo's (z up, facing +x)."""
    return np.asarray(points, np.float64)[..., [2, 0, 1]]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _frame(left: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(T, 3, 3): columns forward, left, up, from a left-pointing and an up-pointing vector."""
    left = _unit(left)
    up = _unit(up - left * np.sum(up * left, -1, keepdims=True))
    return np.stack([np.cross(left, up), left, up], -1)


def _zxy(m: np.ndarray) -> np.ndarray:
    """(T, 3) angles (about z, then x, then y) with m = Rz Rx Ry: the waist's hinge order."""
    roll = np.arcsin(np.clip(m[:, 2, 1], -1, 1))
    return np.stack([np.arctan2(-m[:, 0, 1], m[:, 1, 1]), roll,
                     np.arctan2(-m[:, 2, 0], m[:, 2, 2])], -1)


def _spans(on: np.ndarray) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _hold_weight(on: np.ndarray, blend: int) -> np.ndarray:
    """(T,) 1 on contact frames, easing to 0 within blend frames of them."""
    frames = np.arange(len(on))
    contact = np.flatnonzero(on)
    if not len(contact):
        return np.zeros(len(on))
    distance = np.abs(frames[:, None] - contact[None, :]).min(axis=1)
    x = np.clip(1 - distance / (blend + 1), 0, 1)
    return x * x * (3 - 2 * x)


def _rest_length(a: str, b: str) -> float:
    pose = CHAIN.forward(np.zeros((1, 3)), np.eye(3)[None], np.zeros((1, len(CHAIN.joint_names))))
    return float(np.linalg.norm(pose.pos[0, CHAIN.body(a)] - pose.pos[0, CHAIN.body(b)]))


G1_LEG = _rest_length("left_hip_roll_link", "left_knee_link") + _rest_length(
    "left_knee_link", "left_ankle_roll_link")
G1_ARM = _rest_length("left_shoulder_pitch_link", "left_elbow_link") + _rest_length(
    "left_elbow_link", "left_wrist_yaw_link")


def _arm_error(pose, targets: list[Target]) -> np.ndarray:
    """(T,) an arm's distance to its targets, each weighed as the solver weighs it."""
    return np.sqrt(sum(t.weight * np.sum((pose.point(t.body, t.offset) - t.position) ** 2, -1)
                       for t in targets))


def _foot_targets(h: np.ndarray, j: dict[str, int], side: str, on: np.ndarray, scale: float,
                  heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ankle roll link's target origin (T, 3) and rotation (T, 3, 3) for one foot."""
    ankle, toe = h[:, j[f"{side}_ankle"]], h[:, j[f"{side}_foot"]]
    along = toe - ankle
    # The toe's direction from the ankle, measured from the body's heading: a foot pointing
    # down and back (a kneel's rear foot) is pitched past vertical, not turned round; where it
    # points nearly straight down its yaw is unreliable and eases to the heading.
    turn = np.angle(np.exp(1j * (np.arctan2(along[:, 1], along[:, 0]) - heading)))
    back = np.abs(turn) > np.pi / 2
    turn = np.where(back, np.angle(np.exp(1j * (turn + np.pi))), turn)
    flat = np.linalg.norm(along[:, :2], axis=-1)
    slope = np.arctan2(-along[:, 2], np.where(back, -flat, flat))
    turn = turn * np.clip(2 * flat / np.maximum(np.linalg.norm(along, axis=-1), 1e-9), 0, 1)
    yaw = np.unwrap(heading + turn)
    rest_slope = float(np.median(slope[on])) if on.sum() >= 3 else FOOT_REST_PITCH
    rest_height = float(np.median(ankle[on, 2])) if on.sum() >= 3 else SOLE * scale
    pitch = slope - rest_slope
    position = ankle - np.array([0.0, 0.0, rest_height - SOLE])
    # planted: held where it stands on average over the contact, flat, its sole on the floor
    spans = _spans(on)
    if spans:
        position[:, :2] += correction(position[:, :2], spans, BLEND)
        yaw = yaw + correction(np.stack([yaw, np.zeros_like(yaw)], -1), spans, BLEND)[:, 0]
        w = _hold_weight(on, BLEND)
        pitch = (1 - w) * pitch
        position[:, 2] = (1 - w) * np.maximum(position[:, 2], SOLE) + w * SOLE
    rot = axis_rotation(2, yaw) @ axis_rotation(1, pitch)
    return position, rot


def retarget_g1(joints: np.ndarray, skeleton: Skeleton = HUMANML3D, fps: float | None = None,
                iterations: int = ITERATIONS) -> RobotMotion:
    """The G1's qpos for a (T, 22, 3) HumanML3D joint motion (module doc)."""
    if skeleton.name != HUMANML3D.name:
        raise MlctError(f"the G1 retarget reads HumanML3D's 22 joints, not the {skeleton.name} "
                        f"skeleton's {skeleton.n_joints}")
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, 3) or not len(joints):
        raise MlctError(f"the G1 retarget needs joints of shape (T, {skeleton.n_joints}, 3), "
                        f"got {joints.shape}")
    if not np.isfinite(joints).all():
        raise MlctError("the motion has non-finite joint positions")
    fps = skeleton.fps if fps is None else float(fps)
    joints = joints / units_per_metre(skeleton)
    contacts = foot_contacts(joints, skeleton, fps=fps)
    j = {name: i for i, name in enumerate(skeleton.joint_names)}
    p = to_mujoco(joints)
    leg = np.median(sum(np.linalg.norm(p[:, j[f"{s}_{a}"]] - p[:, j[f"{s}_{b}"]], axis=-1)
                        for s in SIDES for a, b in (("hip", "knee"), ("knee", "ankle"))) / 2)
    scale = G1_LEG / max(float(leg), 1e-6)
    h = p * scale
    frames, n = len(h), len(CHAIN.joint_names)
    q = np.zeros((frames, n))

    # pelvis and waist (analytic)
    hips = _frame(h[:, j["left_hip"]] - h[:, j["right_hip"]],
                  np.broadcast_to([0.0, 0.0, 1.0], (frames, 3)))
    chest = _frame(h[:, j["left_shoulder"]] - h[:, j["right_shoulder"]],
                   h[:, j["neck"]] - h[:, j["spine1"]])
    waist_pitch = CHAIN.joint("waist_pitch_joint")
    bend = _zxy(np.swapaxes(hips, 1, 2) @ chest)[:, 2]
    past = bend - np.clip(bend, CHAIN.lower[waist_pitch], CHAIN.upper[waist_pitch])
    pelvis = hips @ axis_rotation(1, past)
    waist = [CHAIN.joint(f"waist_{a}_joint") for a in ("yaw", "roll", "pitch")]
    q[:, waist] = _zxy(np.swapaxes(pelvis, 1, 2) @ chest)

    # legs and the root's position (least squares)
    hip_mid = (h[:, j["left_hip"]] + h[:, j["right_hip"]]) / 2
    root = hip_mid - pelvis @ np.array([0.0, 0.0, g1.BODIES[2].pos[2] + g1.BODIES[1].pos[2]])
    heading = np.arctan2(pelvis[:, 1, 0], pelvis[:, 0, 0])
    targets, leg_joints, feet = [Target(0, (0.0, 0.0, 0.0), root, (0.3, 0.3, 0.05))], [], {}
    for side, on in zip(SIDES, contacts.T):
        foot_pos, foot_rot = _foot_targets(h, j, side, on, scale, heading)
        feet[side] = foot_pos
        body = CHAIN.body(f"{side}_ankle_roll_link")
        targets.append(Target(body, (0.0, 0.0, 0.0), foot_pos, 1.0))
        for corner in g1.SOLE_CORNERS:
            sole = np.array(corner) - [0.0, 0.0, g1.SOLE_RADIUS]
            targets.append(Target(body, tuple(sole), foot_pos + foot_rot @ sole, 0.5))
        targets.append(Target(CHAIN.body(f"{side}_knee_link"), (0.0, 0.0, 0.0),
                              h[:, j[f"{side}_knee"]], 0.05))
        leg_start(q, h[:, j[f"{side}_hip"]], h[:, j[f"{side}_knee"]], h[:, j[f"{side}_ankle"]],
                   foot_rot, pelvis, side)
        leg_joints += [k for k, name in enumerate(CHAIN.joint_names)
                       if name.startswith(side) and any(part in name for part in
                                                        ("hip", "knee", "ankle"))]
    root, q = solve(CHAIN, root, pelvis, q, leg_joints, targets, move_root=True,
                    iterations=iterations)

    # arms, hung from the G1's shoulders in its torso's frame (least squares)
    pose = CHAIN.forward(root, pelvis, q)
    torso = pose.rot[:, CHAIN.body("torso_link")]
    to_chest = np.swapaxes(chest, 1, 2)
    arm = np.median(sum(np.linalg.norm(p[:, j[f"{s}_{a}"]] - p[:, j[f"{s}_{b}"]], axis=-1)
                        for s in SIDES for a, b in (("shoulder", "elbow"), ("elbow", "wrist")))
                    / 2)
    reach = G1_ARM / max(float(arm), 1e-6) / scale  # h is already scaled by `scale`
    hands = {}
    q = CHAIN.clamp(q)
    for side in SIDES:
        shoulder = pose.pos[:, CHAIN.body(f"{side}_shoulder_pitch_link")]
        hung = {}
        for part in ("elbow", "wrist"):
            local = np.einsum("tij,tj->ti", to_chest, h[:, j[f"{side}_{part}"]] -
                              h[:, j[f"{side}_shoulder"]]) * reach
            hung[part] = shoulder + np.einsum("tij,tj->ti", torso, local)
        hands[side] = hung["wrist"]
        targets = [Target(CHAIN.body(f"{side}_elbow_link"), (0.0, 0.0, 0.0), hung["elbow"],
                          ELBOW_WEIGHT),
                   Target(CHAIN.body(f"{side}_wrist_yaw_link"), (0.0, 0.0, 0.0), hung["wrist"],
                          1.0)]
        arm = [CHAIN.joint(f"{side}_{name}_joint") for name in
               ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")]
        # A few starts (the splittings nearest the limits): near a limit the nearest can lead
        # the solver into a corner another start avoids. Each frame keeps the best, the first
        # unless another is over a centimetre closer (fewer switches between solutions).
        best, best_error = q.copy(), np.full(frames, np.inf)
        for rank, own_hinge in ARM_STARTS:
            # only the frames the starts so far leave over a centimetre off try the next
            rows = np.flatnonzero(best_error > ARM_SWITCH)
            if not len(rows):
                break
            start = q[rows].copy()
            arm_start(start, torso[rows], shoulder[rows], hung["elbow"][rows],
                      hung["wrist"][rows], side, rank, own_hinge)
            here = [Target(t.body, t.offset, t.position[rows], t.weight) for t in targets]
            _, solved = solve(CHAIN, root[rows], pelvis[rows], CHAIN.clamp(start), arm, here,
                              iterations=iterations)
            error = _arm_error(CHAIN.forward(root[rows], pelvis[rows], solved), here)
            better = error < best_error[rows] - (ARM_SWITCH if rank or not own_hinge else 0)
            best[rows[better]] = solved[better]
            best_error[rows[better]] = error[better]
        q[:, arm] = best[:, arm]

    quat = matrix_to_quat(pelvis)
    # q and -q are one rotation: each frame's sign follows the previous one, so that a reader
    # interpolating between frames never swings the long way round
    flips = np.cumsum(np.concatenate([[0], np.sum(quat[1:] * quat[:-1], -1) < 0])) % 2
    quat = np.where(flips[:, None] == 1, -quat, quat)
    qpos = np.concatenate([root, quat, q], -1)
    return RobotMotion(
        g1.NAME, fps, CHAIN.joint_names, qpos, h, scale, contacts,
        {"left_foot": feet["left"], "right_foot": feet["right"], "left_hand": hands["left"],
         "right_hand": hands["right"]})


def forward(motion: RobotMotion):
    """Forward kinematics of a RobotMotion's qpos (chain.Pose of every G1 body)."""
    from mlct.motion.robots.chain import quat_to_matrix

    qpos = np.asarray(motion.qpos, np.float64)
    return CHAIN.forward(qpos[:, :3], quat_to_matrix(qpos[:, 3:7]), qpos[:, 7:])
