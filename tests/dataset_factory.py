"""Small hand-made datasets in the standard layout for the data tests (no synth generator)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mlct.motion.skeleton import HUMANML3D, Skeleton

# Real HumanML3D caption lines (from the HumanML3D README) and a sub-clip variant.
CAPTIONS = [
    "a man kicks something or someone with his left leg.#a/DET man/NOUN kick/VERB "
    "something/PRON or/CCONJ someone/PRON with/ADP his/DET left/ADJ leg/NOUN#0.0#0.0",
    "he is flying kick with his left leg#he/PRON is/AUX fly/VERB kick/NOUN with/ADP his/DET "
    "left/ADJ leg/NOUN#0.0#0.0",
    "a person walks forward.#a/DET person/NOUN walk/VERB forward/ADV#0.0#0.0",
]
# Distinct words of CAPTIONS' tokens.
VOCABULARY = {"a", "man", "kick", "something", "or", "someone", "with", "his", "left", "leg",
              "he", "is", "fly", "person", "walk", "forward"}


def rest_pose(skeleton: Skeleton) -> np.ndarray:
    """(J, 3) joints of the skeleton's rest pose, feet on the floor."""
    joints = np.zeros((skeleton.n_joints, 3))
    for j, parent in enumerate(skeleton.parents):  # parents precede children in both skeletons
        if parent >= 0:
            joints[j] = joints[parent] + skeleton.rest_offsets[j]
    joints[:, 1] -= joints[:, 1].min()
    return joints


def write_motion(root: Path, name: str, frames: int, skeleton: Skeleton = HUMANML3D,
                 captions: list[str] | None = None, seed: int = 0,
                 joints: bool = True) -> np.ndarray:
    """Write features (random), joints (the rest pose, standing still) and texts of one motion."""
    rng = np.random.default_rng(seed)
    features = rng.normal(size=(frames, skeleton.feature_dim)).astype(np.float32)
    (root / "new_joint_vecs").mkdir(parents=True, exist_ok=True)
    np.save(root / "new_joint_vecs" / f"{name}.npy", features)
    if joints:
        (root / "new_joints").mkdir(parents=True, exist_ok=True)
        pose = np.repeat(rest_pose(skeleton)[None], frames, axis=0).astype(np.float32)
        np.save(root / "new_joints" / f"{name}.npy", pose)
    (root / "texts").mkdir(parents=True, exist_ok=True)
    lines = CAPTIONS if captions is None else captions
    (root / "texts" / f"{name}.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return features


def make_dataset(root: Path, lengths: dict[str, int] | None = None,
                 skeleton: Skeleton = HUMANML3D,
                 splits: dict[str, list[str]] | None = None,
                 captions: dict[str, list[str]] | None = None,
                 mean_std: bool = True) -> dict[str, np.ndarray]:
    """A clean dataset: motions of the given lengths, splits, Mean/Std. Returns the features."""
    if lengths is None:
        lengths = {"000001": 60, "000002": 80, "M000001": 60, "000003": 120, "000004": 100}
    features = {}
    for i, (name, frames) in enumerate(lengths.items()):
        features[name] = write_motion(root, name, frames, skeleton,
                                      (captions or {}).get(name), seed=i)
    if splits is None:
        names = list(lengths)
        splits = {"train": names[:-2], "val": names[-2:-1], "test": names[-1:]}
    for split, names in splits.items():
        (root / f"{split}.txt").write_text("".join(f"{n}\n" for n in names), encoding="utf-8")
    if mean_std:
        stacked = np.concatenate(list(features.values()))
        np.save(root / "Mean.npy", stacked.mean(0).astype(np.float32))
        np.save(root / "Std.npy", (stacked.std(0) + 0.5).astype(np.float32))
    return features
