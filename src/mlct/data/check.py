"""Validate a dataset in the standard layout and list every problem with its file.

Each Problem prints as one line, `path[:line]: message`, and carries a `kind` (the rule that
found it) for programs. A bad file never raises: it becomes a problem. Only bad usage raises
MlctError (no such directory, unknown skeleton name).

Rules (kind): missing directories (missing_dir); features without captions (missing_text) or
joints (missing_joints); captions or joints without features (orphan_text, orphan_joints);
unreadable or truncated files (unreadable); feature width against the skeleton, or the majority
width when no skeleton is known (width); wrong array shapes or joint counts (shape); joints whose
frame count differs from the features' (frames_mismatch; new_joints are recovered from the
features, so T matches); NaN/inf (nonfinite); empty or ill-formed caption lines (text); motions
and sub-clips outside the skeleton's length filter, sub-clips past the motion's end (length);
split files missing, entries without files, duplicates (missing_split, split_entry, duplicate);
Mean/Std missing, of the wrong shape, non-finite or with zero std (mean_std); a width that
matches no skeleton (skeleton).
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mlct.data.captions import TextLineError, TextRecord, parse_text_line
from mlct.data.layout import (
    SPLITS,
    BadFileError,
    DatasetLayout,
    feature_problems,
    joints_problems,
    load_npy,
    mean_std_problems,
    read_text_lines,
    resolve_skeleton,
    split_name_problem,
    width_problems,
)
from mlct.errors import MlctError
from mlct.motion.skeleton import Skeleton, skeleton_for_dim


@dataclass(frozen=True)
class Problem:
    """One problem of one file: prints as `path[:line]: message`."""

    path: Path
    message: str
    kind: str
    line: int | None = None

    def __str__(self) -> str:
        where = f"{self.path}:{self.line}" if self.line is not None else f"{self.path}"
        return f"{where}: {self.message}"


def check_dataset(directory: str | os.PathLike,
                  skeleton: Skeleton | str | None = None) -> list[Problem]:
    """Every problem found in the dataset at `directory`, sorted by file (empty: clean)."""
    layout = DatasetLayout.existing(directory)
    checker = _Checker(layout, resolve_skeleton(skeleton))
    checker.run()
    return sorted(checker.problems, key=lambda p: (str(p.path), p.line or 0))


def _repeating_splits(root: Path) -> set[str]:
    """Splits whose synth.json says they repeat motions on purpose (`mlct data oversample`,
    or a merge of such datasets); an unreadable synth.json allows none."""
    from mlct.data.labels import read_synth_meta
    from mlct.data.oversample import repeating_splits

    try:
        return repeating_splits(read_synth_meta(root))
    except MlctError:
        return set()


class _Checker:
    """One pass over a dataset, collecting problems."""

    def __init__(self, layout: DatasetLayout, skeleton: Skeleton | None) -> None:
        self.layout = layout
        self.skeleton = skeleton
        self.problems: list[Problem] = []
        self.feature_frames: dict[str, int] = {}  # name -> T of the well-formed feature files
        self.repeating = _repeating_splits(layout.root)

    def add(self, path: Path, message: str, kind: str, line: int | None = None) -> None:
        """Record a problem."""
        self.problems.append(Problem(path, message, kind, line))

    def run(self) -> None:
        """Apply every rule."""
        layout = self.layout
        for directory in (layout.features_dir, layout.joints_dir, layout.texts_dir):
            if not directory.is_dir():
                self.add(directory, "missing directory", "missing_dir")
        features = layout.feature_names()
        joints = layout.joint_names()
        texts = layout.text_names()
        feature_set, joint_set, text_set = set(features), set(joints), set(texts)
        self.check_features(features)
        self.check_joints(joints, feature_set)
        self.check_texts(texts, feature_set)
        for name in features:
            path = layout.features_path(name)
            if layout.texts_dir.is_dir() and name not in text_set:
                self.add(path, f"no captions ({layout.text_path(name)} missing)", "missing_text")
            if layout.joints_dir.is_dir() and name not in joint_set:
                self.add(path, f"no joints ({layout.joints_path(name)} missing)",
                         "missing_joints")
        self.check_splits(feature_set, text_set)
        self.check_mean_std()

    def expected_width(self, shapes: dict[str, tuple[int, ...]]) -> int | None:
        """The skeleton's feature width, else the majority width (setting the skeleton if known)."""
        if self.skeleton is not None:
            return self.skeleton.feature_dim
        widths = Counter(shape[1] for shape in shapes.values() if len(shape) == 2)
        if not widths:
            return None
        width = widths.most_common(1)[0][0]
        try:
            self.skeleton = skeleton_for_dim(width)
        except ValueError:
            self.add(self.layout.features_dir, f"the majority feature width {width} matches no "
                     f"skeleton (263 humanml3d, 251 kit); pass --skeleton", "skeleton")
        return width

    def check_features(self, names: list[str]) -> None:
        """Readability, shape, width, finiteness and length of the feature files."""
        # One array in memory at a time: keep shapes, then judge widths against the majority.
        shapes: dict[str, tuple[int, ...]] = {}
        for name in names:
            path = self.layout.features_path(name)
            array = self.load(path)
            if array is None:
                continue
            shapes[name] = array.shape
            for kind, message in feature_problems(array, None):
                self.add(path, message, kind)
        width = self.expected_width(shapes)
        for name, shape in shapes.items():
            if len(shape) != 2:
                continue
            path = self.layout.features_path(name)
            for kind, message in width_problems(shape[1], width):
                self.add(path, message, kind)
            if shape[0] == 0:
                continue
            self.feature_frames[name] = shape[0]
            if self.skeleton is not None and not self.in_range(shape[0]):
                self.add(path, f"{shape[0]} frames: {self.range_text()}", "length")

    def check_joints(self, names: list[str], features: set[str]) -> None:
        """Orphans, readability, shape, finiteness and frame count of the joint files."""
        n_joints = self.skeleton.n_joints if self.skeleton else None
        for name in names:
            path = self.layout.joints_path(name)
            if self.layout.features_dir.is_dir() and name not in features:
                self.add(path, f"joints without features ({self.layout.features_path(name)} "
                         f"missing)", "orphan_joints")
            array = self.load(path)
            if array is None:
                continue
            for kind, message in joints_problems(array, n_joints):
                self.add(path, message, kind)
            frames = self.feature_frames.get(name)
            if array.ndim == 3 and frames is not None and array.shape[0] != frames:
                self.add(path, f"{array.shape[0]} frames, but the features have {frames}",
                         "frames_mismatch")

    def check_texts(self, names: list[str], features: set[str]) -> None:
        """Orphans, readability and every caption line of the text files."""
        for name in names:
            path = self.layout.text_path(name)
            if self.layout.features_dir.is_dir() and name not in features:
                self.add(path, f"captions without features ({self.layout.features_path(name)} "
                         f"missing)", "orphan_text")
            try:
                lines = read_text_lines(path)
            except BadFileError as error:
                self.add(path, error.detail, "unreadable")
                continue
            if not lines:
                self.add(path, "no captions (empty file)", "text")
            for number, line in enumerate(lines, start=1):
                try:
                    record = parse_text_line(line)
                except TextLineError as error:
                    self.add(path, str(error), "text", number)
                    continue
                self.check_subclip(path, number, record, self.feature_frames.get(name))

    def check_subclip(self, path: Path, number: int, record: TextRecord,
                      frames: int | None) -> None:
        """A sub-clip caption must lie within its motion and pass the length filter."""
        if self.skeleton is None or frames is None:
            return
        span = record.frame_span(self.skeleton.fps)
        if span is None:
            return
        begin, end = span
        where = f"sub-clip {record.start:g}-{record.end:g} s (frames {begin}..{end - 1})"
        if end > frames:
            self.add(path, f"{where} ends after the motion ({frames} frames)", "length", number)
        elif not self.in_range(end - begin):
            self.add(path, f"{where}: {end - begin} frames, {self.range_text()}", "length",
                     number)

    def check_splits(self, features: set[str], texts: set[str]) -> None:
        """Split files present; entries unique and with their files."""
        layout = self.layout
        for split in SPLITS:
            if not layout.split_path(split).is_file():
                self.add(layout.split_path(split), "missing split file", "missing_split")
        for split in layout.splits():
            path = layout.split_path(split)
            try:
                lines = read_text_lines(path)
            except BadFileError as error:
                self.add(path, error.detail, "unreadable")
                continue
            first_line: dict[str, int] = {}
            repeats = split in self.repeating  # oversampled on purpose: repeats are no problem
            for number, line in enumerate(lines, start=1):
                name = line.strip()
                if not name:
                    continue
                if name in first_line:
                    if not repeats:
                        self.add(path, f"{name!r} listed again (first on line "
                                       f"{first_line[name]})", "duplicate", number)
                    continue
                first_line[name] = number
                problem = split_name_problem(name)
                if problem:  # never joined to the dataset's folders
                    self.add(path, problem, "split_entry", number)
                    continue
                # A missing directory is reported once; its files are not listed per entry.
                missing = [str(path_) for path_, have, directory in (
                    (layout.features_path(name), name in features, layout.features_dir),
                    (layout.text_path(name), name in texts, layout.texts_dir))
                    if directory.is_dir() and not have]
                if missing:
                    self.add(path, f"{name!r} has no {' and no '.join(missing)}", "split_entry",
                             number)

    def check_mean_std(self) -> None:
        """Mean.npy and Std.npy present, of the feature width, finite, std > 0."""
        width = self.skeleton.feature_dim if self.skeleton else None
        for path, is_std in ((self.layout.mean_path, False), (self.layout.std_path, True)):
            if not path.is_file():
                self.add(path, "missing (write it with `mlct data stats`)", "mean_std")
                continue
            array = self.load(path)
            if array is not None:
                for kind, message in mean_std_problems(array, width, is_std):
                    self.add(path, message, kind)

    def load(self, path: Path) -> np.ndarray | None:
        """The array at `path`, or None after recording why it cannot be read."""
        try:
            return load_npy(path)
        except BadFileError as error:
            self.add(path, error.detail, "unreadable")
        except Exception as error:  # noqa: BLE001 - a bad file must never stop the check
            self.add(path, f"unreadable ({type(error).__name__}: {error})", "unreadable")
        return None

    def in_range(self, frames: int) -> bool:
        """The skeleton's length filter: min_frames <= frames < max_frames."""
        assert self.skeleton is not None
        return self.skeleton.min_frames <= frames < self.skeleton.max_frames

    def range_text(self) -> str:
        """The length filter, in words."""
        assert self.skeleton is not None
        return (f"outside the {self.skeleton.name} length filter "
                f"{self.skeleton.min_frames}..{self.skeleton.max_frames - 1} frames "
                f"(the datasets drop it)")

