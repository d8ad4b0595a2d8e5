"""The control's world: the result starts where the prefix or edited motion does, or a full
pose at frame 0, or the path's frame-0 waypoint (facing its heading when given); the network
makes the motion facing +Z at the origin, so the targets are moved into that frame (an
Anchor), and the result back out."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mlct.generate.control.fit import turn_y
from mlct.generate.control.schema import Control


@dataclass(frozen=True)
class Anchor:
    """Where the network's frame (origin, facing +Z) sits in the control's world."""

    origin: np.ndarray  # (3,) with y = 0
    angle: float  # radians about +y

    def to_world(self, points: np.ndarray) -> np.ndarray:
        return turn_y(points, self.angle) + self.origin

    def to_model(self, points: np.ndarray) -> np.ndarray:
        return turn_y(points - self.origin, -self.angle)


def anchor_of(control: Control, skeleton: Any) -> Anchor:
    """The frame the motion starts in: see the module docstring."""
    from mlct.generate.control.facing import heading

    start = control.prefix if control.prefix is not None else control.edit
    pose = None if start is None else start[0]
    if pose is None:
        full = [k for k in control.keyframes if k.frame == 0
                and len(k.joints) == skeleton.n_joints]
        if full:
            pose = np.array([full[0].joints[j] for j in range(skeleton.n_joints)])
    if pose is not None:
        return Anchor(pose[0] * np.array([1.0, 0.0, 1.0]), float(heading(pose, skeleton)))
    if control.path is not None and control.path_frames is not None \
            and 0 in control.path_frames.tolist():
        k = control.path_frames.tolist().index(0)
        angle = 0.0
        if control.heading is not None and np.isfinite(control.heading[k]):
            angle = float(control.heading[k])
        x, z = control.path[k]
        return Anchor(np.array([x, 0.0, z]), angle)
    return Anchor(np.zeros(3), 0.0)


def keyframe_list(control: Control, anchor: Anchor) -> list[tuple[int, dict[int, np.ndarray]]]:
    """Every keyframe, the prefix's frames among them, in the network's frame."""
    keys = [(k.frame, {j: anchor.to_model(np.asarray(p, dtype=np.float64))
                       for j, p in k.joints.items()}) for k in control.keyframes]
    if control.prefix is not None:
        local = anchor.to_model(control.prefix)
        keys += [(f, dict(enumerate(local[f]))) for f in range(len(local))]
    return keys
