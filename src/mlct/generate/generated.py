"""What generation returns: one GeneratedMotion per text, gathered in a Generation.

    out = mlct.load().generate(["a person jumps twice", "a person waves"], seconds=[4, 3])
    out.joints      # (B, T, J, 3), T = the longest; shorter motions hold their last pose
    out.lengths     # (B,) frames of each motion
    out[0].joints   # (T_0, J, 3), just that motion
    out.save("jump.bvh")   # one motion: that file; several: jump_000.bvh, jump_001.bvh, ...
    out[0].save("jump.glb", rig="mixamo")  # a skinned humanoid with Mixamo's joint names
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence, overload

import numpy as np


@dataclass
class GeneratedMotion:
    """One generated motion in real units: features (T, D), joints (T, J, 3), y up."""

    text: str
    features: np.ndarray
    joints: np.ndarray
    fps: float
    skeleton: str
    seed: int | None = None

    @property
    def seconds(self) -> float:
        return len(self.joints) / self.fps

    def save(self, path: str | os.PathLike, features: bool = False,
             rig: str | os.PathLike | None = None) -> Path:
        """Write to path: .gif .mp4 .png .npy .json .bvh .glb .vrma .npz (mlct.generate.exports);
        rig: mixamo, unreal, unity, vrm, smpl or a .json rig, for .bvh and .glb."""
        from mlct.generate.exports import save_motion

        return save_motion(self, path, features, rig)


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
