"""Controls: what a generated motion must do besides following its text. One schema for the
command line (`mlct generate --path --keyframes --edit --parts --prefix`), the Python API
(`pipe.generate(text, control=Control(...))`) and POST /generate (the same JSON object).

    {"path": [[0, 0], [0.5, 2, 40], {"x": 2, "z": 3, "frame": 100, "heading": 90}],
     "trajectory": [[x, z], ...],                       # dense: one point per frame
     "keyframes": [{"frame": 40, "pose": [[x, y, z] x 22]},            # a full pose
                   {"frame": 60, "joint": "left_wrist", "position": [x, y, z]},
                   {"frame": 80, "joints": {"right_wrist": [x, y, z]}}],
     "edit": [[[x, y, z] x 22] x T] | "motion.npy",    # keep this motion ...
     "parts": "upper" | ["left_arm", "head"],          # ... but make these joints anew
     "prefix": [[[x, y, z] x 22] x P] | "motion.npy",  # continue this motion
     "start_pose": [[x, y, z] x 22], "end_pose": [[x, y, z] x 22]}      # in-betweening

Coordinates are metres, y up, in the world of the result. A path's heading is in degrees about
+y, 0 facing +Z, 90 facing +X. Frames index the result (0 .. frames-1); waypoints given without
frames are spread over the whole motion in proportion to the path's length. `Control.check`
validates against a length and a skeleton and raises MlctError with one line naming the problem.
The command line's files: control/files.py. How controls are met: control/controlled.py.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.motion.body_parts import PARTS, joint_index
from mlct.motion.body_parts import part_joints as body_part_joints
from mlct.motion.skeleton import Skeleton

@dataclass(frozen=True)
class Keyframe:
    """Joint positions at one frame: every joint (a full pose) or some (end-effector targets)."""

    frame: int
    joints: Mapping[int, tuple[float, float, float]]  # joint index -> (x, y, z)


@dataclass(frozen=True)
class Control:
    """Every control of one motion; all optional (an empty Control is plain generation)."""

    path: np.ndarray | None = None  # (K, 2) x, z of the root (pelvis) on the floor
    path_frames: np.ndarray | None = None  # (K,) frames, or None: spread by arc length
    heading: np.ndarray | None = None  # (K,) radians per waypoint, NaN where free
    keyframes: tuple[Keyframe, ...] = ()
    edit: np.ndarray | None = None  # (T, J, 3) the motion a body-part edit keeps
    parts: tuple[int, ...] = ()  # the edited joints (descendants included)
    prefix: np.ndarray | None = None  # (P, J, 3) the motion to continue
    source: str = field(default="", compare=False)  # where it was read from, for messages

    @property
    def empty(self) -> bool:
        return (self.path is None and not self.keyframes and self.edit is None
                and self.prefix is None)

    def natural_length(self) -> int | None:
        """The length the control implies: the edited motion's; None when it implies none."""
        return None if self.edit is None else len(self.edit)

    def merged(self, other: Control) -> Control:
        """This control with `other`'s fields where other sets them (CLI flags on a file)."""
        return Control(
            path=other.path if other.path is not None else self.path,
            path_frames=other.path_frames if other.path is not None else self.path_frames,
            heading=other.heading if other.path is not None else self.heading,
            keyframes=self.keyframes + other.keyframes,
            edit=other.edit if other.edit is not None else self.edit,
            parts=other.parts or self.parts,
            prefix=other.prefix if other.prefix is not None else self.prefix,
            source=other.source or self.source)

    def check(self, frames: int, skeleton: Skeleton) -> Control:
        """Validate against a motion of `frames` frames on `skeleton`; returns self, with the
        waypoints' frames filled in. MlctError, one line, on the first problem."""
        j = skeleton.n_joints
        where = f" ({self.source})" if self.source else ""
        if self.path is not None:
            if self.path.ndim != 2 or self.path.shape[1] != 2 or len(self.path) < 1:
                raise MlctError(f"path must be a list of [x, z] points, got shape "
                                f"{self.path.shape}{where}")
            _finite(self.path, "path")
            if self.path_frames is not None:
                _frames_in_range(self.path_frames, frames, "path")
                if len(set(self.path_frames.tolist())) != len(self.path_frames):
                    raise MlctError(f"path: two waypoints at the same frame{where}")
        if self.heading is not None and (self.path is None or len(self.heading) != len(self.path)):
            raise MlctError(f"heading needs one value per path waypoint{where}")
        seen: set[tuple[int, int]] = set()
        for key in self.keyframes:
            _frames_in_range(np.array([key.frame]), frames, "keyframe")
            for joint, pos in key.joints.items():
                if not 0 <= joint < j:
                    raise MlctError(f"keyframe at frame {key.frame}: joint {joint} is not one "
                                    f"of the {j} joints{where}")
                _finite(np.asarray(pos, dtype=float), f"keyframe at frame {key.frame}")
                if (key.frame, joint) in seen:
                    raise MlctError(f"keyframes: joint {skeleton.joint_names[joint]} is given "
                                    f"twice at frame {key.frame}{where}")
                seen.add((key.frame, joint))
        for name, motion in (("edit", self.edit), ("prefix", self.prefix)):
            if motion is None:
                continue
            if motion.ndim != 3 or motion.shape[1:] != (j, 3):
                raise MlctError(f"{name} motion must be joints of shape (T, {j}, 3), got "
                                f"{motion.shape}{where}")
            _finite(motion, f"{name} motion")
        if self.edit is not None:
            if len(self.edit) != frames:
                raise MlctError(f"an edit keeps the motion's length: {len(self.edit)} frames, "
                                f"but {frames} were asked for")
            if not self.parts:
                raise MlctError("an edit needs the parts to make anew: --parts upper "
                                f"(one of {', '.join(PARTS)}) or joint names")
        elif self.parts:
            raise MlctError("parts name what an edit changes; give the motion to edit (--edit)")
        if self.prefix is not None and not 2 <= len(self.prefix) < frames:
            raise MlctError(f"a prefix of {len(self.prefix)} frames cannot be continued to "
                            f"{frames} frames: ask for more frames than the prefix has")
        if self.path is not None and self.path_frames is None:
            return replace(self, path_frames=spread_by_length(self.path, frames))
        return self


def spread_by_length(path: np.ndarray, frames: int) -> np.ndarray:
    """Frames for waypoints given without: the first at 0, the last at frames-1, the rest in
    proportion to the distance along the path (a constant speed)."""
    if len(path) == 1:
        return np.zeros(1, dtype=np.int64)
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    share = along / along[-1] if along[-1] > 0 else np.linspace(0.0, 1.0, len(path))
    out = np.round(share * (frames - 1)).astype(np.int64)
    if len(set(out.tolist())) != len(out):
        raise MlctError(f"{len(path)} waypoints do not fit in {frames} frames at distinct "
                        f"frames; give fewer waypoints or frames for them")
    return out


def _finite(values: np.ndarray, what: str) -> None:
    if not np.isfinite(values).all():
        raise MlctError(f"{what} contains NaN or inf")


def _frames_in_range(values: np.ndarray, frames: int, what: str) -> None:
    bad = values[(values < 0) | (values >= frames)]
    if bad.size:
        raise MlctError(f"{what} frame {int(bad[0])} is outside 0..{frames - 1} (the motion "
                        f"has {frames} frames)")


# ----------------------------------------------------------------------------- parsing


def part_joints(parts: str | Sequence[str], skeleton: Skeleton) -> tuple[int, ...]:
    """The joints an edit makes anew: named parts (motion/body_parts.py) with descendants;
    never the pelvis, which carries the kept motion's path."""
    chosen = body_part_joints(parts, skeleton)
    if 0 in chosen:
        raise MlctError("an edit keeps the pelvis (the root): name limbs or 'upper'/'lower'")
    return chosen


def _array(value: Any, what: str, ndim: int | None = None) -> np.ndarray:
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise MlctError(f"{what} must hold numbers") from None
    if ndim is not None and out.ndim != ndim:
        raise MlctError(f"{what} must be a {ndim}-d array of numbers, got shape {out.shape}")
    return out


def _frame(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value != int(value):
        raise MlctError(f"{what}: frame must be a whole number, got {value!r}")
    return int(value)


def _motion(value: Any, what: str, skeleton: Skeleton) -> np.ndarray:
    """Joints (T, J, 3) from an array, a nested list or a .npy file of joints or features."""
    if isinstance(value, (str, os.PathLike)):
        try:
            value = np.load(Path(value), allow_pickle=False)
        except (OSError, ValueError) as error:
            raise MlctError(f"cannot read the {what} motion {value}: {first_line(error)}") from None
    motion = _array(value, f"{what} motion")
    if motion.ndim == 2 and motion.shape[1] == skeleton.feature_dim:
        from mlct.motion.features import features_to_joints

        motion = features_to_joints(motion, skeleton.n_joints)
    if motion.ndim != 3 or motion.shape[1:] != (skeleton.n_joints, 3):
        raise MlctError(f"{what} motion must be joints (T, {skeleton.n_joints}, 3) or features "
                        f"(T, {skeleton.feature_dim}), got shape {motion.shape}")
    return motion


def _waypoints(items: Any) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    if not isinstance(items, (list, tuple)) or not items:
        raise MlctError("path must be a non-empty list of waypoints [x, z] or [x, z, frame]")
    xz, frames, heads = [], [], []
    for i, item in enumerate(items):
        if isinstance(item, Mapping):
            unknown = set(item) - {"x", "z", "frame", "heading"}
            if unknown or "x" not in item or "z" not in item:
                raise MlctError(f"path[{i}]: a waypoint has x, z and optionally frame, heading; "
                                f"got keys {sorted(item)}")
            point, frame, head = [item["x"], item["z"]], item.get("frame"), item.get("heading")
        elif isinstance(item, (list, tuple)) and len(item) in (2, 3):
            point, frame, head = list(item[:2]), (item[2] if len(item) == 3 else None), None
        else:
            raise MlctError(f"path[{i}]: a waypoint is [x, z], [x, z, frame] or an object, "
                            f"got {item!r}")
        xz.append(_array(point, f"path[{i}]", 1))
        frames.append(None if frame is None else _frame(frame, f"path[{i}]"))
        heads.append(np.nan if head is None else float(_array(head, f"path[{i}] heading", 0)))
    if len({f is None for f in frames}) > 1:
        raise MlctError("path: give a frame for every waypoint or for none")
    frame_arr = None if frames[0] is None else np.array(frames, dtype=np.int64)
    head_arr = np.radians(np.array(heads)) if not np.isnan(heads).all() else None
    return np.stack(xz), frame_arr, head_arr


def _keyframe(item: Any, i: int, skeleton: Skeleton) -> Keyframe:
    if not isinstance(item, Mapping) or "frame" not in item:
        raise MlctError(f"keyframes[{i}]: an object with a frame and a pose, a joint and "
                        f"position, or joints")
    unknown = set(item) - {"frame", "pose", "joint", "position", "joints"}
    if unknown:
        raise MlctError(f"keyframes[{i}]: unknown field {sorted(unknown)[0]!r} (expected "
                        f"frame, pose, joint, position or joints)")
    frame = _frame(item["frame"], f"keyframes[{i}]")
    joints: dict[int, tuple[float, float, float]] = {}
    if "pose" in item:
        pose = _array(item["pose"], f"keyframes[{i}] pose")
        if pose.shape != (skeleton.n_joints, 3):
            raise MlctError(f"keyframes[{i}]: a pose is {skeleton.n_joints} [x, y, z] points, "
                            f"got shape {pose.shape}")
        joints.update({j: tuple(p) for j, p in enumerate(pose)})
    if "joint" in item or "position" in item:
        if "joint" not in item or "position" not in item:
            raise MlctError(f"keyframes[{i}]: give both joint and position")
        joints[joint_index(item["joint"], skeleton)] = _point(item["position"], f"keyframes[{i}]")
    for name, pos in dict(item.get("joints") or {}).items():
        joints[joint_index(name, skeleton)] = _point(pos, f"keyframes[{i}] {name}")
    if not joints:
        raise MlctError(f"keyframes[{i}]: no joint positions (pose, joint + position, or joints)")
    return Keyframe(frame, joints)


def _point(value: Any, what: str) -> tuple[float, float, float]:
    point = _array(value, what)
    if point.shape != (3,):
        raise MlctError(f"{what}: a position is [x, y, z], got shape {point.shape}")
    return (float(point[0]), float(point[1]), float(point[2]))


CONTROL_FIELDS = ("path", "trajectory", "keyframes", "edit", "parts", "prefix", "start_pose",
                  "end_pose")


def control_from_dict(data: Mapping[str, Any], skeleton: Skeleton, source: str = "",
                      frames: int | None = None) -> Control:
    """A Control from the JSON schema above; MlctError naming the first bad field."""
    if not isinstance(data, Mapping):
        raise MlctError(f"a control is a JSON object with fields {', '.join(CONTROL_FIELDS)}")
    unknown = set(data) - set(CONTROL_FIELDS)
    if unknown:
        raise MlctError(f"unknown control field {sorted(unknown)[0]!r}; expected "
                        f"{', '.join(CONTROL_FIELDS)}")
    path = frames_of = heading = None
    if data.get("path") is not None and data.get("trajectory") is not None:
        raise MlctError("give a path (waypoints) or a trajectory (one point per frame), not both")
    if data.get("path") is not None:
        path, frames_of, heading = _waypoints(data["path"])
    if data.get("trajectory") is not None:
        path = _array(data["trajectory"], "trajectory", 2)
        if path.shape[-1] != 2:
            raise MlctError(f"trajectory must be [x, z] points, got shape {path.shape}")
        frames_of = np.arange(len(path), dtype=np.int64)
    keys_in = data.get("keyframes") or []
    if not isinstance(keys_in, (list, tuple)):
        raise MlctError("keyframes must be a list of objects")
    keys = [_keyframe(item, i, skeleton) for i, item in enumerate(keys_in)]
    for name, frame in (("start_pose", 0), ("end_pose", -1)):
        if data.get(name) is not None:
            if frame < 0 and frames is None:
                raise MlctError("end_pose needs the motion's length (give seconds or lengths)")
            at = frame if frame >= 0 else int(frames) - 1  # type: ignore[arg-type]
            keys.append(_keyframe({"frame": at, "pose": data[name]}, len(keys), skeleton))
    edit = None if data.get("edit") is None else _motion(data["edit"], "edit", skeleton)
    prefix = None if data.get("prefix") is None else _motion(data["prefix"], "prefix", skeleton)
    parts = () if data.get("parts") is None else part_joints(data["parts"], skeleton)
    return Control(path=path, path_frames=frames_of, heading=heading, keyframes=tuple(keys),
                   edit=edit, parts=parts, prefix=prefix, source=source)
