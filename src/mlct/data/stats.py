"""Dataset normalization statistics (Mean.npy / Std.npy) and a descriptive report.

Mean/Std follow HumanML3D's cal_mean_variance: over every frame of every feature file (all
splits, mirrored copies included, no length filter), the per-feature mean, and the per-feature
population std averaged within each feature group (root rotation velocity, root linear velocity,
root height, ric, rotations, local velocity, foot contact), so that a group is scaled as a whole.
Files with NaN are skipped with a note, as there.
"""

from __future__ import annotations

import math
import os
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from mlct.data.layout import BadFileError, DatasetLayout, is_mirrored
from mlct.errors import MlctError
from mlct.io import save_npy
from mlct.motion.physics import foot_skating_ratio
from mlct.motion.skeleton import Skeleton

# A group whose averaged std is below this is constant over the dataset. The reference would
# store ~0 and divide by it later; we store 1.0 instead: the group normalizes to 0 either way,
# and a model's small errors on that group are not amplified by 1e8 when denormalizing.
TINY_STD = 1e-8
HISTOGRAM_BINS = 10


class RunningMeanStd:
    """Per-feature mean and population std over streamed (T, D) arrays (Chan et al.'s merge)."""

    def __init__(self, dim: int) -> None:
        self.count = 0
        self.mean = np.zeros(dim, dtype=np.float64)
        self._m2 = np.zeros(dim, dtype=np.float64)  # sum of squared deviations from the mean

    def update(self, frames: np.ndarray) -> None:
        """Add the rows of a (T, D) array."""
        frames = np.asarray(frames, dtype=np.float64)
        n_b = frames.shape[0]
        if n_b == 0:
            return
        mean_b = frames.mean(axis=0)
        m2_b = ((frames - mean_b) ** 2).sum(axis=0)
        n = self.count + n_b
        delta = mean_b - self.mean
        # Merging per-file moments keeps memory at O(D) and stays accurate in float64.
        self.mean = self.mean + delta * (n_b / n)
        self._m2 = self._m2 + m2_b + delta**2 * (self.count * n_b / n)
        self.count = n

    @property
    def std(self) -> np.ndarray:
        """Population std (ddof = 0, as numpy's default in the reference)."""
        return np.sqrt(self._m2 / max(self.count, 1))


def group_averaged_std(std: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, list[str]]:
    """Average `std` within each feature group; constant groups get 1.0. Returns (std, groups)."""
    std = np.asarray(std, dtype=np.float64).copy()
    if std.shape != (skeleton.feature_dim,):
        raise ValueError(f"std of shape {std.shape} for {skeleton.feature_dim}-d features")
    constant = []
    for name, group in skeleton.layout.groups.items():
        value = std[group].mean()
        if value < TINY_STD:
            constant.append(name)
            value = 1.0
        std[group] = value
    return std, constant


def standard_mean_std(features: Iterable[np.ndarray],
                      skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(Mean, Std, constant groups) of (T, D) arrays the HumanML3D way, as float32."""
    running = RunningMeanStd(skeleton.feature_dim)
    for array in features:
        running.update(array)
    if running.count == 0:
        raise MlctError("no usable feature frames to compute Mean/Std from")
    std, constant = group_averaged_std(running.std, skeleton)
    return running.mean.astype(np.float32), std.astype(np.float32), constant


def _usable(names: list[str], load: Callable[[str, Skeleton], np.ndarray], skeleton: Skeleton,
            notes: list[str]) -> Iterator[tuple[str, np.ndarray]]:
    """(name, array) of each file `load` reads; an unusable file is skipped with a note."""
    for name in names:
        try:
            array = load(name, skeleton)
        except BadFileError as error:
            notes.append(f"skipped {error}")
            continue
        yield name, array


def dataset_statistics(directory: str | os.PathLike, skeleton: Skeleton | str | None = None,
                       write_mean_std: bool = True) -> dict[str, Any]:
    """Describe a dataset (counts, lengths, vocabulary, foot skating) and write its Mean/Std."""
    layout = DatasetLayout.existing(directory)
    if not layout.features_dir.is_dir():
        raise MlctError(f"{layout.root}: no {layout.features_dir.name}/ directory "
                        f"(not a dataset in the standard layout)")
    skel = layout.skeleton(skeleton)
    notes: list[str] = []
    stats: dict[str, Any] = {"root": str(layout.root), "skeleton": skel.name, "fps": skel.fps,
                             "feature_dim": skel.feature_dim, "notes": notes}

    # Features: lengths and moments, one file in memory at a time. NaN files are skipped as in
    # the reference; so are unusable ones (unreadable, wrong width), each with a note.
    lengths: dict[str, int] = {}

    def usable_features() -> Iterator[np.ndarray]:
        for name, array in _usable(layout.feature_names(), layout.load_features, skel, notes):
            lengths[name] = array.shape[0]
            yield array

    if not layout.feature_names():
        raise MlctError(f"{layout.features_dir}: no feature files")
    try:
        mean, std, constant = standard_mean_std(usable_features(), skel)
    except MlctError:  # every file was skipped
        raise MlctError(f"{layout.features_dir}: no usable feature files "
                        f"(first problem: {notes[0] if notes else 'none'})") from None
    stats.update(_length_statistics(list(lengths.values()), skel))
    stats["motions"] = len(lengths)
    stats["mirrored"] = sum(is_mirrored(name) for name in lengths)
    for group in constant:
        notes.append(f"feature group {group!r} is constant over the dataset: its std is set to 1")
    stats["mean_std"] = {"written": False, "constant_groups": constant,
                         "mean_path": str(layout.mean_path), "std_path": str(layout.std_path)}
    stats.update(_text_statistics(layout, notes))
    stats["splits"] = _split_statistics(layout, set(lengths), skel, lengths)
    stats.update(_skating_statistics(layout, skel, notes))
    if write_mean_std:  # last: a dataset that fails a check above (a bad split) is left as it was
        save_npy(layout.mean_path, mean)
        save_npy(layout.std_path, std)
        stats["mean_std"]["written"] = True
    return stats


def _length_statistics(lengths: list[int], skeleton: Skeleton) -> dict[str, Any]:
    """Frame counts, hours, length range and an integer-bin histogram."""
    array = np.asarray(lengths)
    frames = int(array.sum())
    lo, hi = int(array.min()), int(array.max())
    width = max(1, math.ceil((hi - lo + 1) / HISTOGRAM_BINS))
    edges = lo + width * np.arange(HISTOGRAM_BINS + 1)
    counts, _ = np.histogram(array, bins=edges)
    in_range = (array >= skeleton.min_frames) & (array < skeleton.max_frames)
    return {
        "frames": frames,
        "hours": frames / skeleton.fps / 3600.0,
        "length": {"min": lo, "max": hi, "mean": float(array.mean()),
                   "in_range": int(in_range.sum()), "min_frames": skeleton.min_frames,
                   "max_frames": skeleton.max_frames},
        # Bins [lo, hi) in frames, `width` frames each; empty trailing bins are kept for shape.
        "histogram": [{"lo": int(a), "hi": int(b), "count": int(c)}
                      for a, b, c in zip(edges[:-1], edges[1:], counts)],
    }


def _text_statistics(layout: DatasetLayout, notes: list[str]) -> dict[str, Any]:
    """Caption counts, vocabulary size (distinct words of the word/POS tokens), caption length."""
    vocabulary: set[str] = set()
    captions = subclips = words = files = 0
    for name in layout.text_names():
        try:
            records = layout.read_texts(name)
        except BadFileError as error:
            notes.append(f"skipped {error}")
            continue
        files += 1
        for record in records:
            captions += 1
            subclips += not record.whole_clip
            words += len(record.tokens)
            vocabulary.update(record.words)
    return {"text_files": files, "captions": captions, "subclip_captions": subclips,
            "vocabulary": len(vocabulary), "words_per_caption": words / max(captions, 1)}


def _split_statistics(layout: DatasetLayout, usable: set[str], skeleton: Skeleton,
                      lengths: dict[str, int]) -> dict[str, dict[str, int]]:
    """Per split: names listed, names with usable features, and those within the length filter."""
    splits = {}
    for split in layout.splits():
        names = layout.read_split(split)
        present = [n for n in names if n in usable]
        in_range = [n for n in present
                    if skeleton.min_frames <= lengths[n] < skeleton.max_frames]
        splits[split] = {"names": len(names), "with_features": len(present),
                         "in_range": len(in_range)}
    return splits


def _skating_statistics(layout: DatasetLayout, skeleton: Skeleton,
                        notes: list[str]) -> dict[str, Any]:
    """Mean foot-skating ratio over the joint files (mlct.motion.physics.foot_skating_ratio)."""
    ratios = [foot_skating_ratio(joints, skeleton)
              for _, joints in _usable(layout.joint_names(), layout.load_joints, skeleton, notes)]
    return {"joint_files": len(ratios),
            "foot_skating_ratio": float(np.mean(ratios)) if ratios else None}


def format_statistics(stats: dict[str, Any]) -> str:
    """A readable multi-line report of dataset_statistics' result."""
    length = stats["length"]
    lines = [
        f"dataset    {stats['root']} ({stats['skeleton']}, {stats['fps']:g} fps, "
        f"{stats['feature_dim']} features)",
        f"motions    {stats['motions']:,} ({stats['mirrored']:,} mirrored), "
        f"{stats['frames']:,} frames, {stats['hours']:.2f} hours",
        f"lengths    min {length['min']}, mean {length['mean']:.1f}, max {length['max']} frames; "
        f"{length['in_range']:,} within the length filter "
        f"{length['min_frames']}..{length['max_frames'] - 1}",
        f"captions   {stats['captions']:,} in {stats['text_files']:,} text files "
        f"({stats['subclip_captions']:,} of sub-clips), vocabulary {stats['vocabulary']:,} "
        f"words, {stats['words_per_caption']:.1f} words per caption",
    ]
    if stats["splits"]:
        parts = [f"{name} {s['names']:,} ({s['with_features']:,} with features, "
                 f"{s['in_range']:,} in range)" for name, s in stats["splits"].items()]
        lines.append("splits     " + "; ".join(parts))
    else:
        lines.append("splits     none")
    if stats["foot_skating_ratio"] is None:
        lines.append("skating    no joint files")
    else:
        lines.append(f"skating    foot-skating ratio {stats['foot_skating_ratio']:.4f} "
                     f"(mean over {stats['joint_files']:,} joint files)")
    mean_std = stats["mean_std"]
    if mean_std["written"]:
        lines.append(f"Mean/Std   written to {mean_std['mean_path']} and {mean_std['std_path']}")
    else:
        lines.append("Mean/Std   not written")
    lines.append("length histogram (frames):")
    peak = max(b["count"] for b in stats["histogram"]) or 1
    for b in stats["histogram"]:
        bar = "#" * round(40 * b["count"] / peak)
        lines.append(f"  {b['lo']:>4}-{b['hi'] - 1:<4} {b['count']:>7,} {bar}".rstrip())
    if stats["notes"]:
        lines.append(f"notes ({len(stats['notes'])}; `mlct data check` lists every problem):")
        shown = stats["notes"][:20]
        lines.extend(f"  - {note}" for note in shown)
        if len(stats["notes"]) > len(shown):
            lines.append(f"  ... and {len(stats['notes']) - len(shown)} more")
    return "\n".join(lines)
