"""Motion .npy files as `mlct render` and `mlct retarget` read them: features or joints, the
skeleton from the shape, every problem a one-line MlctError. Apart from render.py so that a
retarget, which draws nothing, does not import matplotlib (~0.1 s of its start)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, TypeVar

import numpy as np

from mlct.errors import MlctError, first_line
from mlct.motion.skeleton import (SKELETONS, Skeleton, get_skeleton, skeleton_for_dim,
                                  skeleton_for_joints)

T = TypeVar("T")


def load_motion_npy(path: str | os.PathLike,
                    skeleton: Skeleton | str | None = None) -> tuple[np.ndarray, Skeleton]:
    """(T, J, 3) joints and their skeleton from a features (T, 263|251) or joints (T, J, 3)
    .npy file (features are turned into joints); the skeleton comes from the shape unless
    given. Every problem is a one-line MlctError. `mlct render` and `mlct retarget` read
    motions with it."""
    path = Path(path)
    array = _load_npy(path)
    feature_dims = sorted(s.feature_dim for s in SKELETONS.values())
    is_features = array.ndim == 2 and array.shape[1] in feature_dims
    if not is_features and not (array.ndim == 3 and array.shape[2] == 3):
        widths = " or ".join(f"(T, {d})" for d in feature_dims)
        raise MlctError(f"{path} has shape {array.shape}: expected features {widths}, "
                        f"or joints (T, J, 3)")
    if len(array) == 0:
        raise MlctError(f"{path} has no frames (shape {array.shape})")
    check_finite(array, str(path))

    if skeleton is not None:
        skel = resolve_skeleton(skeleton)
    elif is_features:
        skel = _call(skeleton_for_dim, array.shape[1])
    else:
        skel = _call(skeleton_for_joints, array.shape[1])
    if is_features:
        if skel.feature_dim != array.shape[1]:
            raise MlctError(f"{path} has {array.shape[1]}-d features but the {skel.name} "
                            f"skeleton uses {skel.feature_dim}")
        from mlct.motion.joints import features_to_joints

        joints = features_to_joints(array.astype(np.float32), skel.n_joints)
        check_finite(joints, f"joints recovered from {path}")
    else:
        if skel.n_joints != array.shape[1]:
            raise MlctError(f"{path} has {array.shape[1]} joints but the {skel.name} skeleton "
                            f"has {skel.n_joints}")
        joints = array
    return joints, skel


def resolve_skeleton(skeleton: Skeleton | str) -> Skeleton:
    """A skeleton or its name as a Skeleton; a one-line MlctError for an unknown name."""
    if isinstance(skeleton, Skeleton):
        return skeleton
    return _call(get_skeleton, skeleton)


def _call(lookup: Callable[[T], Skeleton], arg: T) -> Skeleton:
    """Turn the skeleton look-ups' ValueError into the user's one-line error."""
    try:
        return lookup(arg)
    except ValueError as error:
        raise MlctError(str(error)) from None


def check_finite(array: np.ndarray, what: str) -> None:
    """A one-line MlctError naming the frames of `array` that hold NaN or inf."""
    bad = ~np.isfinite(array)
    if bad.any():
        frames = np.nonzero(bad.reshape(len(array), -1).any(axis=1))[0]
        raise MlctError(f"{what} has {int(bad.sum())} NaN/inf values in {len(frames)} frame(s), "
                        f"first at frame {int(frames[0])}")


def _load_npy(path: Path) -> np.ndarray:
    try:
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise MlctError(f"{path}: no such file") from None
    except (OSError, ValueError, EOFError) as error:
        reason = first_line(error)
        raise MlctError(f"cannot read {path} as .npy: {reason}") from None
    if not isinstance(array, np.ndarray):  # an .npz archive
        raise MlctError(f"{path} is not a single .npy array")
    if array.dtype.kind not in "fiu":
        raise MlctError(f"{path} holds {array.dtype} values, not numbers")
    return array
