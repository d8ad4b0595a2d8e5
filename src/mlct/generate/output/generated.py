"""What generation returns: one GeneratedMotion per text, gathered in a Generation.

    out = mlct.load().generate(["a person jumps twice", "a person waves"], seconds=[4, 3])
    out.joints      # (B, T, J, 3), T = the longest; shorter motions hold their last pose
    out.lengths     # (B,) frames of each motion
    out[0].joints   # (T_0, J, 3), just that motion
    out.save("jump.bvh")   # one motion: that file; several: jump_000.bvh, jump_001.bvh, ...
    out[0].save("jump.glb", rig="mixamo")  # a skinned humanoid with Mixamo's joint names
    out[0].unknown_parts  # (): the model knows the prompt; else the parts it does not know
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence, overload

import numpy as np


@dataclass
class GeneratedMotion:
    """One generated motion in real units: features (T, D), joints (T, J, 3), y up.

    features may be given as None: they are then derived from the joints (HumanML3D's
    processing, motion/features.py) when first read. The pipeline does that when it has moved
    the joints after decoding (planted feet, motion/foot_lock.py): the derivation costs ~8 ms
    per 10-s motion, and most callers only ever read the joints."""

    text: str
    features: np.ndarray | None
    joints: np.ndarray
    fps: float
    skeleton: str
    seed: int | None = None
    # the parts of the prompt (all of it, or some of its actions as generate() splits them)
    # that lie too far from every training caption for the model to know them: their motion
    # is likely not what was asked (generate/compose/unknown_prompts.py); () when it knows them all
    unknown_parts: tuple[str, ...] = ()

    @property
    def seconds(self) -> float:
        return len(self.joints) / self.fps

    @property
    def known(self) -> bool:
        """False when some part of the prompt is unknown to the model (unknown_parts)."""
        return not self.unknown_parts

    def renamed(self, text: str) -> GeneratedMotion:
        """The same motion under another text (its features not derived by the copy)."""
        return dataclasses.replace(self, text=text, features=self._features)

    def in_place(self) -> GeneratedMotion:
        """The motion without its travel over the ground: the pelvis stays over where it
        started (its height, the turns and every pose as they were), as a game engine's
        "in place" clip whose root motion the engine applies itself. A copy; its features are
        derived from the new joints when read."""
        joints = np.array(self.joints, copy=True)
        travel = joints[:, :1, [0, 2]] - joints[:1, :1, [0, 2]]  # (T, 1, 2) the pelvis's xz
        joints[..., [0, 2]] -= travel
        return dataclasses.replace(self, joints=joints, features=None)

    def save(self, path: str | os.PathLike, features: bool = False,
             rig: str | os.PathLike | None = None) -> Path:
        """Write to path: .gif .mp4 .png .npy .json .bvh .glb .fbx .vrma .npz
        (mlct.generate.output.exports); rig: mixamo, unreal, unity, vrm, smpl or a .json rig, for .bvh,
        .glb and .fbx."""
        from mlct.generate.output.exports import save_motion

        return save_motion(self, path, features, rig)


def _features(motion: GeneratedMotion) -> np.ndarray:
    if motion._features is None:
        from mlct.motion.features import joints_to_features
        from mlct.motion.skeleton import get_skeleton

        # joints_to_features gives one frame fewer (velocities are frame differences): the
        # last pose held one more frame keeps features and joints the same length
        joints = np.asarray(motion.joints, np.float64)
        joints = np.concatenate([joints, joints[-1:]])
        motion._features = joints_to_features(joints, get_skeleton(motion.skeleton)).features
    return motion._features


def _set_features(motion: GeneratedMotion, value: np.ndarray | None) -> None:
    motion._features = value


# Set after the dataclass is made, so that its generated __init__ (features=...) and
# dataclasses.replace go through the property: None there means "derive when read".
GeneratedMotion.features = property(_features, _set_features)  # type: ignore[method-assign,assignment]


def _padded(arrays: Sequence[np.ndarray]) -> np.ndarray:
    # Past its end a motion holds its last frame: a still pose, not zeros (a body at the origin)
    # and not NaN (which breaks every plot); `lengths` says where each one really ends.
    if not arrays:
        return np.empty((0,), dtype=np.float32)
    longest = max(len(a) for a in arrays)
    out = np.empty((len(arrays), longest, *arrays[0].shape[1:]), dtype=arrays[0].dtype)
    for i, a in enumerate(arrays):
        out[i, :len(a)] = a
        out[i, len(a):] = a[-1]
    return out


class Generation(Sequence[GeneratedMotion]):
    """The motions of one generate() call, in the order of its texts."""

    def __init__(self, motions: Sequence[GeneratedMotion]) -> None:
        self.motions = list(motions)

    @overload
    def __getitem__(self, index: int) -> GeneratedMotion: ...
    @overload
    def __getitem__(self, index: slice) -> Generation: ...

    def __getitem__(self, index: int | slice) -> GeneratedMotion | Generation:
        if isinstance(index, slice):
            return Generation(self.motions[index])
        return self.motions[index]

    def __len__(self) -> int:
        return len(self.motions)

    def __iter__(self) -> Iterator[GeneratedMotion]:
        return iter(self.motions)

    def __repr__(self) -> str:
        return f"Generation({len(self)} motions, lengths={self.lengths.tolist()})"

    @property
    def texts(self) -> list[str]:
        return [m.text for m in self.motions]

    @property
    def unknown_parts(self) -> list[tuple[str, ...]]:
        """Each motion's unknown_parts: () where the model knows its prompt."""
        return [m.unknown_parts for m in self.motions]

    @property
    def lengths(self) -> np.ndarray:
        """(B,) frames of each motion."""
        return np.array([len(m.joints) for m in self.motions], dtype=np.int64)

    @property
    def joints(self) -> np.ndarray:
        """(B, T, J, 3), padded to the longest by holding each motion's last pose."""
        return _padded([m.joints for m in self.motions])

    @property
    def features(self) -> np.ndarray:
        """(B, T, D), padded like joints."""
        return _padded([m.features for m in self.motions])

    def save(self, path: str | os.PathLike, features: bool = False,
             rig: str | os.PathLike | None = None) -> list[Path]:
        """Write every motion: path itself for one, else path's stem with _000, _001, ..."""
        path = Path(path)
        if len(self) == 1:
            return [self.motions[0].save(path, features, rig)]
        return [m.save(path.with_name(f"{path.stem}_{i:03d}{path.suffix}"), features, rig)
                for i, m in enumerate(self.motions)]
