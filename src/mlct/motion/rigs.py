"""Retarget presets: the joint names, rest pose, axes and units of the rigs people animate.

A rig file drops onto a character when its skeleton speaks the character's language: the same
joint names (a retargeter maps by name), a rest pose like the character's (T-pose or A-pose: the
rotations are relative to it), the up axis and the unit of the tools it goes to. mlct's
HumanML3D skeleton is the SMPL body's first 22 joints, so every preset is a renaming of those
22 joints plus a rest pose and a frame; `Rig.axes` turns mlct's frame (y up, facing +Z, the
body's left on +X, metres) into the rig's.

Facts, from each rig's public documentation and the projects that read it:
- mixamo: Mixamo's auto-rigger names, "mixamorig:" + Hips, Spine, Spine1, Spine2, Neck, Head,
  LeftShoulder, LeftArm, LeftForeArm, LeftHand, LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase;
  T-pose; Y up, facing +Z; centimetres (its FBX files).
- unreal: the UE4/UE5 Mannequin skeleton, pelvis, spine_01..03, neck_01, head, clavicle_l,
  upperarm_l, lowerarm_l, hand_l, thigh_l, calf_l, foot_l, ball_l; arms down at about 45
  degrees (A-pose); Z up, facing +Y as its skeletal mesh does (right-handed here: Unreal's
  importers flip Y themselves); centimetres.
- unity: the Mecanim Humanoid avatar's bone names (Hips, Spine, Chest, UpperChest, Neck, Head,
  LeftShoulder, LeftUpperArm, LeftLowerArm, LeftHand, LeftUpperLeg, LeftLowerLeg, LeftFoot,
  LeftToes); T-pose (what "Enforce T-Pose" makes); Y up, facing +Z; metres.
- vrm: the VRM 1.0 humanoid bone names (hips, spine, chest, upperChest, neck, head,
  leftShoulder, leftUpperArm, leftLowerArm, leftHand, leftUpperLeg, leftLowerLeg, leftFoot,
  leftToes); T-pose (VRM 1.0 requires it); Y up, facing +Z; metres.
- smpl: the SMPL body's joint names in its order (pelvis, left_hip, right_hip, spine1, ...:
  HumanML3D's own); T-pose with the arms out (SMPL's zero pose); Y up, facing +Z; metres.

A user's rig: `--rig FILE.json`, {"name": ..., "joints": {mlct joint name: rig joint name, all
22}, "rest": "T" | "A" | "native" (or "rest_directions": {mlct joint name: [x, y, z]} in mlct's
frame), "up": "y" | "z", "forward": "+z" | "-z" | "+y" | "-y" | "+x" | "-x", "unit": "m" | "cm"}.

Formats with fixed conventions take only what they can use: glTF/GLB is y up in metres by its
specification, so a preset changes its names and rest pose; BVH takes all of it.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.motion.skeleton import HUMANML3D, Skeleton

UNITS = {"m": 1.0, "cm": 100.0}  # per metre
AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1),
        "-z": (0, 0, -1)}

# The 22 HumanML3D (SMPL) joints, in order, under each preset's names.
_SIDES = ("left", "right")
_NAMES: dict[str, tuple[str, ...]] = {
    "mixamo": tuple("mixamorig:" + n for n in (
        "Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1", "LeftFoot",
        "RightFoot", "Spine2", "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder",
        "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm", "RightForeArm",
        "LeftHand", "RightHand")),
    "unreal": (
        "pelvis", "thigh_l", "thigh_r", "spine_01", "calf_l", "calf_r", "spine_02", "foot_l",
        "foot_r", "spine_03", "ball_l", "ball_r", "neck_01", "clavicle_l", "clavicle_r", "head",
        "upperarm_l", "upperarm_r", "lowerarm_l", "lowerarm_r", "hand_l", "hand_r"),
    "unity": (
        "Hips", "LeftUpperLeg", "RightUpperLeg", "Spine", "LeftLowerLeg", "RightLowerLeg",
        "Chest", "LeftFoot", "RightFoot", "UpperChest", "LeftToes", "RightToes", "Neck",
        "LeftShoulder", "RightShoulder", "Head", "LeftUpperArm", "RightUpperArm",
        "LeftLowerArm", "RightLowerArm", "LeftHand", "RightHand"),
    "vrm": (
        "hips", "leftUpperLeg", "rightUpperLeg", "spine", "leftLowerLeg", "rightLowerLeg",
        "chest", "leftFoot", "rightFoot", "upperChest", "leftToes", "rightToes", "neck",
        "leftShoulder", "rightShoulder", "head", "leftUpperArm", "rightUpperArm",
        "leftLowerArm", "rightLowerArm", "leftHand", "rightHand"),
    "smpl": HUMANML3D.joint_names,
}
# preset -> (rest pose, up, forward, unit)
_FRAMES = {"mixamo": ("T", "+y", "+z", "cm"), "unreal": ("A", "+z", "+y", "cm"),
           "unity": ("T", "+y", "+z", "m"), "vrm": ("T", "+y", "+z", "m"),
           "smpl": ("T", "+y", "+z", "m")}
PRESETS = tuple(_NAMES)

# Arm bones (joint index -> its bone's direction from the parent) of the two rest poses, left
# arm (+x); the right arm mirrors x. The collar -> shoulder bone is out and a little up in both.
_ARMS = {"T": {16: (1.0, 0.1, -0.05), 18: (1.0, 0.0, 0.0), 20: (1.0, 0.0, 0.0)},
         "A": {16: (1.0, 0.1, -0.05), 18: (0.71, -0.71, 0.0), 20: (0.71, -0.71, 0.0)}}
_RIGHT = {16: 17, 18: 19, 20: 21}


def rest_pose(kind: str, skeleton: Skeleton = HUMANML3D) -> np.ndarray:
    """(J, 3) unit bone directions of a "T", "A" or "native" (the skeleton's own) rest pose."""
    rest = np.array(skeleton.rest_directions, dtype=np.float64)
    if kind == "native":
        return rest
    if kind not in _ARMS:
        raise MlctError(f"unknown rest pose {kind!r}: choose T, A or native")
    for joint, direction in _ARMS[kind].items():
        left = np.array(direction) / np.linalg.norm(direction)
        rest[joint] = left
        rest[_RIGHT[joint]] = left * [-1.0, 1.0, 1.0]
    return rest


def axes_matrix(up: str, forward: str) -> np.ndarray:
    """(3, 3) rotation taking mlct's frame (y up, facing +Z) to one with `up` and `forward`."""
    if up not in AXES or forward not in AXES:
        raise MlctError(f"axes must be one of {', '.join(AXES)}: got up {up!r}, forward "
                        f"{forward!r}")
    u, f = np.array(AXES[up], float), np.array(AXES[forward], float)
    if abs(u @ f) > 0.5:
        raise MlctError(f"up {up} and forward {forward} must be different axes")
    return np.stack([np.cross(u, f), u, f], axis=1)  # columns: images of x, y, z


@dataclass(frozen=True)
class Rig:
    """Names, rest pose and frame of a target rig for the 22 HumanML3D joints."""

    name: str
    joint_names: tuple[str, ...]
    rest_directions: np.ndarray  # (J, 3) in mlct's frame
    axes: np.ndarray  # (3, 3) mlct's frame -> the rig's
    unit: str  # "m" or "cm"

    @property
    def per_metre(self) -> float:
        return UNITS[self.unit]


def preset(name: str) -> Rig:
    rest, up, forward, unit = _FRAMES[name]
    return Rig(name, _NAMES[name], rest_pose(rest), axes_matrix(up, forward), unit)


def _axis(value: object) -> str:
    text = str(value).lower()
    return f"+{text}" if text in ("x", "y", "z") else text


def _rig_from_json(path: Path) -> Rig:
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise MlctError(f"--rig {path}: cannot read ({error.strerror})") from None
    except (ValueError, UnicodeDecodeError) as error:
        raise MlctError(f"--rig {path}: not valid JSON ({first_line(error)})") from None
    if not isinstance(spec, dict) or not isinstance(spec.get("joints"), dict):
        raise MlctError(f"--rig {path}: needs an object with \"joints\": {{mlct joint name: "
                        f"rig joint name}}")
    joints = spec["joints"]
    missing = [n for n in HUMANML3D.joint_names if n not in joints]
    unknown = [n for n in joints if n not in HUMANML3D.joint_names]
    if missing or unknown:
        raise MlctError(f"--rig {path}: \"joints\" must name all 22 mlct joints "
                        f"(missing: {', '.join(missing) or 'none'}; unknown: "
                        f"{', '.join(unknown) or 'none'})")
    names = tuple(joints[n] for n in HUMANML3D.joint_names)
    if not all(isinstance(n, str) and n.strip() and not any(c.isspace() for c in n)
               for n in names) or len(set(names)) != len(names):
        raise MlctError(f"--rig {path}: rig joint names must be distinct non-empty strings "
                        f"without spaces")
    if "rest_directions" in spec:
        given = spec["rest_directions"]
        try:
            rest = np.array([given[n] for n in HUMANML3D.joint_names], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise MlctError(f"--rig {path}: \"rest_directions\" needs [x, y, z] for each of the "
                            f"22 mlct joints") from None
        if rest.shape != (22, 3) or not np.isfinite(rest).all() or \
                (np.linalg.norm(rest[1:], axis=-1) < 1e-9).any():
            raise MlctError(f"--rig {path}: \"rest_directions\" must be 22 finite non-zero "
                            f"[x, y, z] vectors")
        rest = rest / np.maximum(np.linalg.norm(rest, axis=-1, keepdims=True), 1e-12)
    else:
        rest = rest_pose(str(spec.get("rest", "T")))
    unit = str(spec.get("unit", "m"))
    if unit not in UNITS:
        raise MlctError(f"--rig {path}: \"unit\" must be one of {', '.join(UNITS)}, not {unit!r}")
    axes = axes_matrix(_axis(spec.get("up", "+y")), _axis(spec.get("forward", "+z")))
    return Rig(str(spec.get("name", path.stem)), names, rest, axes, unit)


def get_rig(spec: str | os.PathLike | Rig | None, skeleton: Skeleton) -> Rig | None:
    """The Rig a --rig value names: a preset, a .json file, or None (the skeleton's own)."""
    if spec is None or isinstance(spec, Rig):
        if spec is not None and skeleton.name != HUMANML3D.name:
            raise MlctError(f"rig presets retarget the humanml3d skeleton, not {skeleton.name}")
        return spec
    text = str(spec)
    if skeleton.name != HUMANML3D.name:
        raise MlctError(f"--rig retargets the humanml3d (SMPL) skeleton; this motion is "
                        f"{skeleton.name}")
    if text.lower() in _NAMES:
        return preset(text.lower())
    if text.lower().endswith(".json"):
        return _rig_from_json(Path(text))
    raise MlctError(f"unknown rig {text!r}: choose {', '.join(PRESETS)} or a FILE.json")
