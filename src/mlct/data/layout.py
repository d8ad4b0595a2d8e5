"""The standard dataset layout of HumanML3D and KIT-ML, as distributed.

    DIR/new_joint_vecs/NAME.npy   (T, 263 | 251) float32 features
    DIR/new_joints/NAME.npy       (T, J, 3) joint positions (recovered from the features: same T)
    DIR/texts/NAME.txt            lines `caption#word/POS word/POS ...#start#end`
    DIR/{train,val,test}.txt      one NAME per line (optional: train_val.txt, all.txt)
    DIR/Mean.npy, DIR/Std.npy     (D,) normalization statistics

Names starting with `M` are mirrored copies. `start#end` of `0.0#0.0` (or nan) is the whole clip;
otherwise the caption describes the sub-clip `features[int(start*fps):int(end*fps)]`. The reference
(EricGuo5513/text-to-motion data/dataset.py) hard-codes 20 fps there, even for KIT-ML; we cut at
the skeleton's fps (12.5 for KIT-ML), which is what the seconds in the text files mean.

The reader and the checker share the rules below: loaders raise MlctError naming the file, the
checker (mlct.data.check) collects the same messages as problems.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mlct.data.captions import TextLineError, TextRecord, caption_field, parse_text_line
from mlct.errors import MlctError
from mlct.motion.skeleton import Skeleton, get_skeleton, skeleton_for_dim, skeleton_for_joints

FEATURES_DIR = "new_joint_vecs"
JOINTS_DIR = "new_joints"
TEXTS_DIR = "texts"
PROVENANCE_FILE = "provenance.jsonl"  # per motion: source, license (real corpora, merges)
SPLITS = ("train", "val", "test")
OPTIONAL_SPLITS = ("train_val", "all")
MIRROR_PREFIX = "M"


class BadFileError(MlctError):
    """A dataset file that cannot be used: `path[:line]: detail`."""

    def __init__(self, path: str | os.PathLike, detail: str, line: int | None = None) -> None:
        self.path = Path(path)
        self.detail = detail
        self.line = line
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {detail}")


def read_text_lines(path: str | os.PathLike) -> list[str]:
    """The lines of a UTF-8 text file; raise BadFileError if it cannot be read."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise BadFileError(path, f"cannot read: {_reason(error)}") from None
    return text.splitlines()


def read_texts(path: str | os.PathLike) -> list[TextRecord]:
    """All caption records of one text file; raise BadFileError naming file and line."""
    lines = read_text_lines(path)
    if not lines:
        raise BadFileError(path, "no captions (empty file)")
    records = []
    for number, line in enumerate(lines, start=1):
        try:
            records.append(parse_text_line(line))
        except TextLineError as error:
            raise BadFileError(path, str(error), line=number) from None
    return records


def dataset_caption(path: str | os.PathLike) -> str | None:
    """The first caption of a motion file in the standard layout, or None if there is none.

    DIR/new_joint_vecs/NAME.npy and DIR/new_joints/NAME.npy have their captions in
    DIR/texts/NAME.txt. Only the caption field is read: a title is a nicety, so an unreadable
    texts file gives None rather than an error.
    """
    path = Path(path)
    if path.parent.name not in (FEATURES_DIR, JOINTS_DIR):
        return None
    text_file = path.parent.parent / TEXTS_DIR / f"{path.stem}.txt"
    try:
        lines = text_file.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    return next((caption for caption in map(caption_field, lines) if caption), None)


def split_name_problem(name: str) -> str | None:
    """Why a split file's entry is not a motion name, or None. A name is joined to the dataset's
    folders, so one that could leave them (a separator, '..', a leading dot) is refused."""
    if "/" in name or "\\" in name or name.startswith(".") or "\x00" in name:
        return (f"{name[:60]!r} is not a motion name (names are file stems: no '/', '\\' or "
                f"leading '.')")
    return None


def read_split(path: str | os.PathLike) -> list[str]:
    """The names listed in a split file, in order (blank lines ignored, duplicates kept); a
    name that could leave the dataset's folders raises MlctError naming the line."""
    names = []
    for number, line in enumerate(read_text_lines(path), start=1):
        name = line.strip()
        if not name:
            continue
        problem = split_name_problem(name)
        if problem:
            raise MlctError(f"{path}, line {number}: {problem}")
        names.append(name)
    return names


def load_npy(path: str | os.PathLike) -> np.ndarray:
    """np.load without pickles; raise BadFileError for missing, truncated or non-numeric files."""
    try:
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise BadFileError(path, "missing") from None
    except (OSError, ValueError, EOFError) as error:
        # Truncated files raise ValueError ("cannot reshape ..."), non-npy files ValueError or
        # OSError, object arrays ValueError (pickles are refused).
        raise BadFileError(path, f"unreadable .npy ({_reason(error)})") from None
    if not isinstance(array, np.ndarray):
        raise BadFileError(path, "not a single array (.npz?)")
    if array.dtype.kind not in "fiu":
        raise BadFileError(path, f"dtype {array.dtype} is not a real number type")
    return array


# Validation rules return (kind, message) pairs: the loaders raise on the first ones, the checker
# reports them all under their kind.
Finding = tuple[str, str]


def feature_problems(array: np.ndarray, width: int | None) -> list[Finding]:
    """What is wrong with a (T, D) feature array expected to be `width` wide (None: any)."""
    if array.ndim != 2:
        return [("shape", f"shape {array.shape} is not (frames, features)")]
    problems = width_problems(array.shape[1], width)
    if array.shape[0] == 0:
        problems.append(("length", "no frames"))
    problems.extend(_finite_problems(array))
    return problems


def width_problems(found: int, width: int | None) -> list[Finding]:
    """A finding if `found` features per frame is not the expected `width` (None: any)."""
    if width is not None and found != width:
        return [("width", f"{found} features per frame, expected {width}")]
    return []


def joints_problems(array: np.ndarray, n_joints: int | None) -> list[Finding]:
    """What is wrong with a (T, J, 3) joint array expected to have `n_joints` joints (None: any)."""
    if array.ndim != 3 or array.shape[2] != 3:
        return [("shape", f"shape {array.shape} is not (frames, joints, 3)")]
    problems = []
    if n_joints is not None and array.shape[1] != n_joints:
        problems.append(("shape", f"{array.shape[1]} joints, expected {n_joints}"))
    if array.shape[0] == 0:
        problems.append(("length", "no frames"))
    problems.extend(_finite_problems(array))
    return problems


def _finite_problems(array: np.ndarray) -> list[Finding]:
    """A finding counting NaN and inf values, if any."""
    if array.dtype.kind != "f":
        return []
    n_nan = int(np.isnan(array).sum())
    n_inf = int(np.isinf(array).sum())
    if n_nan or n_inf:
        return [("nonfinite", f"{n_nan} NaN and {n_inf} inf values")]
    return []


def _reason(error: BaseException) -> str:
    """The first line of an exception's message."""
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__


def resolve_skeleton(skeleton: Skeleton | str | None) -> Skeleton | None:
    """A Skeleton from a name or instance (None stays None); unknown names raise MlctError."""
    if skeleton is None or isinstance(skeleton, Skeleton):
        return skeleton
    try:
        return get_skeleton(skeleton)
    except ValueError as error:
        raise MlctError(str(error)) from None


@dataclass(frozen=True, init=False)
class DatasetLayout:
    """Paths of a dataset directory in the standard layout, and strict readers for its files."""

    root: Path

    def __init__(self, root: str | os.PathLike) -> None:
        object.__setattr__(self, "root", Path(root))

    @classmethod
    def existing(cls, root: str | os.PathLike) -> DatasetLayout:
        """The layout of `root`, which must be a directory (one line otherwise)."""
        layout = cls(root)
        if not layout.root.is_dir():
            raise MlctError(f"{layout.root}: no such directory")
        return layout

    def skeleton(self, given: Skeleton | str | None = None) -> Skeleton:
        """`given` (a name or a Skeleton), else the one the files imply; one line if neither."""
        skel = resolve_skeleton(given) or self.infer_skeleton()
        if skel is None:
            raise MlctError(f"{self.root}: cannot tell the skeleton from the feature files "
                            f"(263-d HumanML3D or 251-d KIT-ML); name it (humanml3d or kit)")
        return skel

    @property
    def features_dir(self) -> Path:
        return self.root / FEATURES_DIR

    @property
    def joints_dir(self) -> Path:
        return self.root / JOINTS_DIR

    @property
    def texts_dir(self) -> Path:
        return self.root / TEXTS_DIR

    @property
    def mean_path(self) -> Path:
        return self.root / "Mean.npy"

    @property
    def std_path(self) -> Path:
        return self.root / "Std.npy"

    def features_path(self, name: str) -> Path:
        return self.features_dir / f"{name}.npy"

    def joints_path(self, name: str) -> Path:
        return self.joints_dir / f"{name}.npy"

    def text_path(self, name: str) -> Path:
        return self.texts_dir / f"{name}.txt"

    def split_path(self, split: str) -> Path:
        return self.root / f"{split}.txt"

    def feature_names(self) -> list[str]:
        """Sorted names of the feature files."""
        return _stems(self.features_dir, ".npy")

    def joint_names(self) -> list[str]:
        """Sorted names of the joint files."""
        return _stems(self.joints_dir, ".npy")

    def text_names(self) -> list[str]:
        """Sorted names of the text files."""
        return _stems(self.texts_dir, ".txt")

    def splits(self) -> list[str]:
        """The split files present, standard ones first."""
        return [s for s in SPLITS + OPTIONAL_SPLITS if self.split_path(s).is_file()]

    def read_split(self, split: str) -> list[str]:
        """The names of a split; a missing split file raises MlctError."""
        path = self.split_path(split)
        if not path.is_file():
            present = ", ".join(self.splits()) or "none"
            raise MlctError(f"{path}: no such split file (splits present: {present})")
        return read_split(path)

    def read_texts(self, name: str) -> list[TextRecord]:
        """The caption records of `name`."""
        path = self.text_path(name)
        if not path.is_file():
            raise BadFileError(path, "missing")
        return read_texts(path)

    def load_features(self, name: str, skeleton: Skeleton | None = None) -> np.ndarray:
        """(T, D) float32 features of `name`, validated (width of `skeleton`, finite)."""
        path = self.features_path(name)
        array = load_npy(path)
        problems = feature_problems(array, skeleton.feature_dim if skeleton else None)
        if problems:
            raise BadFileError(path, "; ".join(message for _, message in problems))
        return array.astype(np.float32, copy=False)

    def load_joints(self, name: str, skeleton: Skeleton | None = None) -> np.ndarray:
        """(T, J, 3) float32 joint positions of `name`, validated (joint count, finite)."""
        path = self.joints_path(name)
        array = load_npy(path)
        problems = joints_problems(array, skeleton.n_joints if skeleton else None)
        if problems:
            raise BadFileError(path, "; ".join(message for _, message in problems))
        return array.astype(np.float32, copy=False)

    def load_mean_std(self, skeleton: Skeleton | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(D,) Mean and Std, validated: right width, finite, std > 0."""
        arrays = []
        for path in (self.mean_path, self.std_path):
            if not path.is_file():
                raise MlctError(f"{path}: missing (write it with `mlct data stats {self.root}`)")
            array = load_npy(path)
            problems = mean_std_problems(array, skeleton.feature_dim if skeleton else None,
                                         is_std=path == self.std_path)
            if problems:
                raise BadFileError(path, "; ".join(message for _, message in problems))
            arrays.append(array.astype(np.float32))
        mean, std = arrays
        if mean.shape != std.shape:
            raise MlctError(f"{self.mean_path}: shape {mean.shape} differs from Std {std.shape}")
        return mean, std

    def infer_skeleton(self) -> Skeleton | None:
        """The skeleton of the majority feature width (else joint count), or None if unknown."""
        widths = Counter(s[1] for s in _header_shapes(self.features_dir) if len(s) == 2)
        for width, _ in widths.most_common(1):
            try:
                return skeleton_for_dim(width)
            except ValueError:
                pass
        counts = Counter(s[1] for s in _header_shapes(self.joints_dir) if len(s) == 3)
        for n_joints, _ in counts.most_common(1):
            try:
                return skeleton_for_joints(n_joints)
            except ValueError:
                pass
        return None


def mean_std_problems(array: np.ndarray, width: int | None, is_std: bool) -> list[Finding]:
    """What is wrong with a Mean or Std vector for `width` features."""
    if array.ndim != 1:
        return [("mean_std", f"shape {array.shape} is not (features,)")]
    problems = []
    if width is not None and array.shape[0] != width:
        problems.append(("mean_std", f"{array.shape[0]} values, expected {width}"))
    problems.extend(("mean_std", message) for _, message in _finite_problems(array))
    if is_std:
        n_bad = int((array <= 0).sum())
        if n_bad:
            problems.append(("mean_std", f"{n_bad} std values <= 0 (normalizing would divide "
                                         f"by zero)"))
    return problems


def _stems(directory: Path, suffix: str) -> list[str]:
    """Sorted stems of the files with `suffix` in `directory`, skipping dot-files."""
    if not directory.is_dir():
        return []
    # Dot-files are skipped: atomic writers (mlct.io) use dot-prefixed temporary names.
    return sorted(p.name[: -len(suffix)] for p in directory.iterdir()
                  if p.name.endswith(suffix) and not p.name.startswith(".") and p.is_file())


def _header_shapes(directory: Path, limit: int = 200) -> list[tuple[int, ...]]:
    """Shapes of up to `limit` .npy files, read from their headers only."""
    shapes = []
    for name in _stems(directory, ".npy")[:limit]:
        try:
            shapes.append(np.load(directory / f"{name}.npy", mmap_mode="r").shape)
        except (OSError, ValueError, EOFError):
            continue
    return shapes


def is_mirrored(name: str) -> bool:
    """True for the mirrored copies of the standard datasets (`M000001` mirrors `000001`)."""
    return name.startswith(MIRROR_PREFIX)


def read_provenance(root: str | os.PathLike) -> list[dict[str, Any]]:
    """A dataset's provenance.jsonl records in file order ([] when it has none): per motion its
    corpus, source file, labels and license (data/corpora, data/merge)."""
    path = Path(root) / PROVENANCE_FILE
    if not path.is_file():
        return []
    records = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if line.strip():
            try:
                records.append(json.loads(line))
            except json.JSONDecodeError as error:
                raise BadFileError(path, f"not JSON ({error.msg})", line=number) from None
    return records


def provenance_label(record: dict[str, Any]) -> str:
    """What a motion shows, as its corpus labels it: the content (Bandai Namco), else the
    description (CMU's index, lower case)."""
    labels = record.get("labels", {})
    return labels.get("content") or labels.get("description", "?").lower()
