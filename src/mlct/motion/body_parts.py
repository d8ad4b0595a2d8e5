"""Named body parts as joint sets: one table for every consumer (ours).

The body-part edits (generate/control/schema.py, `--parts upper`) and the autoencoder's arm pair
(motion/features.py `arm_feature_columns`) both ask "which joints are the arms"; they ask here.
A part names the joints its limbs hang from and takes their descendants too, so a chosen joint
never leaves a child behind. Each limb root lists the names it goes by in the skeletons we know,
the first one the skeleton has wins: HumanML3D's arms hang from the collars, KIT-ML's (which has
no collars) from the shoulders; HumanML3D's upper body starts at spine1, KIT-ML's at the torso.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from mlct.errors import MlctError
from mlct.motion.skeleton import Skeleton

PARTS: dict[str, tuple[tuple[str, ...], ...]] = {
    "upper": (("spine1", "torso"),),
    "lower": (("left_hip",), ("right_hip",)),
    "legs": (("left_hip",), ("right_hip",)),
    "arms": (("left_collar", "left_shoulder"), ("right_collar", "right_shoulder")),
    "left_arm": (("left_collar", "left_shoulder"),),
    "right_arm": (("right_collar", "right_shoulder"),),
    "left_leg": (("left_hip",),),
    "right_leg": (("right_hip",),),
    "head": (("neck",),),
}


def joint_index(name: Any, skeleton: Skeleton) -> int:
    """A joint given by name ('left_wrist') or index; MlctError naming the choices."""
    if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        if 0 <= int(name) < skeleton.n_joints:
            return int(name)
        raise MlctError(f"joint {name} is not one of the {skeleton.n_joints} joints")
    if isinstance(name, str) and name.strip().lower() in skeleton.joint_names:
        return skeleton.joint_names.index(name.strip().lower())
    raise MlctError(f"unknown joint {name!r}; joints: {', '.join(skeleton.joint_names)}")


def _part_roots(part: str, skeleton: Skeleton) -> list[int]:
    roots = []
    for aliases in PARTS[part]:
        found = [skeleton.joint_names.index(a) for a in aliases if a in skeleton.joint_names]
        if not found:
            raise MlctError(f"the {skeleton.name} skeleton has no joint for part {part!r} "
                            f"(looked for {', '.join(aliases)})")
        roots.append(found[0])
    return roots


def part_joints(parts: str | Sequence[str], skeleton: Skeleton) -> tuple[int, ...]:
    """The joints of named parts ('upper', 'left_arm', ... or joint names), with descendants,
    sorted; parts as a comma-separated string or a sequence of names/indices."""
    names = [p.strip() for p in parts.split(",")] if isinstance(parts, str) else list(parts)
    roots: list[int] = []
    for name in names:
        if isinstance(name, str) and name.lower() in PARTS:
            roots += _part_roots(name.lower(), skeleton)
        else:
            try:
                roots.append(joint_index(name, skeleton))
            except MlctError:
                raise MlctError(f"unknown part {name!r}: one of {', '.join(PARTS)} or a joint "
                                f"name ({', '.join(skeleton.joint_names)})") from None
    if not roots:
        raise MlctError("parts is empty: name a part, e.g. 'upper'")
    chosen = set(roots)
    for joint in range(skeleton.n_joints):  # parents come before children in the skeleton
        if skeleton.parents[joint] in chosen:
            chosen.add(joint)
    return tuple(sorted(chosen))
