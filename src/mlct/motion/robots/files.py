"""A retargeted robot motion as files: MuJoCo-style CSV and .npz.

- .csv: a header row, then one row a frame: time (s), the free joint's position root_x, root_y,
  root_z (m, z up) and orientation root_qw, root_qx, root_qy, root_qz, then the joint angles
  (rad) in the model's joint order, named as its joints: columns 2 to the end are exactly
  MuJoCo's qpos.
- .npz: format, robot, fps, joint_names, qpos (T, 7 + n), human_joints (T, 22, 3: the motion's
  joints the retarget followed, in MuJoCo's frame and scaled), scale, foot_contacts (T, 2: left,
  right) and source (the robot model the angles are for).

Both are written atomically; both read back with read_robot (a one-line MlctError on a file
that is not one).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from mlct.errors import MlctError
from mlct.io import write_bytes, write_text
from mlct.motion.robots import g1
from mlct.motion.robots.retarget import RobotMotion

FORMAT = "mlct-robot"
ROOT_COLUMNS = ("root_x", "root_y", "root_z", "root_qw", "root_qx", "root_qy", "root_qz")
DECIMALS = 6  # a micrometre and a microradian: far below any controller's resolution
ROBOTS = {g1.NAME: g1}


def csv_text(motion: RobotMotion) -> str:
    header = ",".join(("time",) + ROOT_COLUMNS + tuple(motion.joint_names))
    time = np.arange(motion.frames) / motion.fps
    rows = np.concatenate([time[:, None], motion.qpos], 1)
    body = "\n".join(",".join(f"{v:.{DECIMALS}f}" for v in row) for row in rows)
    return f"{header}\n{body}\n"


def npz_bytes(motion: RobotMotion) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer, format=np.array(FORMAT), robot=np.array(motion.robot), fps=np.array(motion.fps),
        joint_names=np.array(motion.joint_names), qpos=motion.qpos.astype(np.float64),
        human_joints=motion.human.astype(np.float32), scale=np.array(motion.scale),
        foot_contacts=motion.contacts.astype(bool), source=np.array(ROBOTS[motion.robot].SOURCE))
    return buffer.getvalue()


def write_robot(path: str | os.PathLike, motion: RobotMotion) -> Path:
    """Write motion as .csv or .npz (module doc); returns the path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        write_text(path, csv_text(motion))
    elif suffix == ".npz":
        write_bytes(path, npz_bytes(motion))
    else:
        raise MlctError(f"a robot motion is written as .csv or .npz, not '{path.name}'")
    return path


def read_robot(path: str | os.PathLike) -> RobotMotion:
    """A RobotMotion from a file write_robot wrote (the CSV keeps qpos and fps only)."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".csv":
            return _read_csv(path)
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data or str(data["format"]) != FORMAT:
                raise MlctError(f"{path} is not an {FORMAT} .npz (no format '{FORMAT}')")
            return RobotMotion(str(data["robot"]), float(data["fps"]),
                               tuple(str(n) for n in data["joint_names"]), data["qpos"],
                               data["human_joints"].astype(np.float64), float(data["scale"]),
                               data["foot_contacts"])
    except (OSError, ValueError, KeyError) as error:
        raise MlctError(f"cannot read {path}: {str(error).splitlines()[0]}") from None


def _read_csv(path: Path) -> RobotMotion:
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines or tuple(lines[0].split(",")[:8]) != ("time",) + ROOT_COLUMNS:
        raise MlctError(f"{path} is not a robot motion CSV (its header must start with time, "
                        f"{', '.join(ROOT_COLUMNS)})")
    names = tuple(lines[0].split(",")[8:])
    robot = next((r for r in ROBOTS.values() if r.JOINT_NAMES == names), None)
    if robot is None:
        raise MlctError(f"{path}: its {len(names)} joint columns are no known robot's")
    rows = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    if rows.shape[1] != 8 + len(names):
        raise MlctError(f"{path}: rows of {rows.shape[1]} values under {8 + len(names)} columns")
    fps = round(1.0 / float(np.median(np.diff(rows[:, 0]))), 3) if len(rows) > 1 else 0.0
    return RobotMotion(robot.NAME, fps, names, rows[:, 1:], np.zeros((len(rows), 0, 3)), 1.0)
