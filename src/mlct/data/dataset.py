"""Torch datasets of caption-motion pairs, as the standard Text2MotionDatasetV2.

Facts from EricGuo5513/text-to-motion data/dataset.py (Text2MotionDatasetV2), which the
evaluation protocol and the MLD/MLCT code bases share:
- a split's motions are kept when min_frames <= T < max_frames (HumanML3D 40..199, KIT 24..199);
- captions with `0.0#0.0` describe the whole motion and are grouped on one item; every sub-clip
  caption becomes an item of its own, the motion cut at the skeleton's fps (the reference uses
  20 fps for both datasets) and length-filtered the same way;
- motions are normalized by Mean/Std;
- each access picks a random caption, crops the length to a multiple of unit_length (4),
  dropping one more unit with probability 1/3 (the reference's coin 'single'/'single'/'double'),
  takes a random window of that length and pads with zeros to max_motion_length (196).

Unlike the reference, a bad or missing file is never skipped silently: strict by default
(MlctError naming the file), or on_bad_file="skip" with one counted warning. Randomness comes
from a seed or torch.Generator; in DataLoader workers from the worker's seed.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple, Sequence

import numpy as np
import torch
from torch.utils.data import Dataset, get_worker_info

from mlct.data.captions import TextRecord
from mlct.data.layout import BadFileError, DatasetLayout
from mlct.errors import MlctError
from mlct.motion.skeleton import Skeleton

UNIT_LENGTH = 4
MAX_MOTION_LENGTH = 196
MAX_TEXT_LENGTH = 20  # tokens kept for the evaluator's text encoder


class Sample(NamedTuple):
    """One training item: caption, its word/POS tokens, (max_len, D) motion, valid frames."""

    caption: str
    tokens: list[str]
    motion: torch.Tensor
    length: int


class EvalSample(NamedTuple):
    """An evaluation item: tokens wrapped in sos/eos and padded with unk; sent_len counts them."""

    caption: str
    tokens: list[str]
    motion: torch.Tensor
    length: int
    sent_len: int


@dataclass(frozen=True)
class _Item:
    """A motion (normalized, float32) and the captions that describe all of it."""

    name: str
    motion: np.ndarray  # (T, D)
    captions: tuple[TextRecord, ...]


class Text2MotionDataset(Dataset):
    """Caption-motion pairs of one split, held in memory, normalized, randomly cropped."""

    def __init__(self, root: str | os.PathLike, split: str = "train", *,
                 skeleton: Skeleton | str | None = None,
                 mean: np.ndarray | None = None, std: np.ndarray | None = None,
                 unit_length: int = UNIT_LENGTH, max_motion_length: int = MAX_MOTION_LENGTH,
                 on_bad_file: Literal["strict", "skip"] = "strict",
                 seed: int | None = None, generator: torch.Generator | None = None) -> None:
        if on_bad_file not in ("strict", "skip"):
            raise ValueError(f"on_bad_file must be 'strict' or 'skip', not {on_bad_file!r}")
        if unit_length < 1 or max_motion_length < unit_length:
            raise ValueError(f"need 1 <= unit_length ({unit_length}) <= max_motion_length "
                             f"({max_motion_length})")
        self.layout = DatasetLayout.existing(root)
        self.skeleton = skel = self.layout.skeleton(skeleton)
        self.split = split
        self.unit_length = unit_length
        self.max_motion_length = max_motion_length
        # The evaluator's statistics may differ from the dataset's: mean/std can be given.
        if (mean is None) != (std is None):
            raise ValueError("pass both mean and std, or neither (then DIR/Mean.npy, Std.npy)")
        if mean is None or std is None:
            mean, std = self.layout.load_mean_std(skel)
        self.mean = np.asarray(mean, dtype=np.float32)
        self.std = np.asarray(std, dtype=np.float32)
        if self.mean.shape != (skel.feature_dim,) or self.std.shape != (skel.feature_dim,):
            raise MlctError(f"mean/std of shapes {self.mean.shape}, {self.std.shape} do not fit "
                            f"{skel.feature_dim}-d {skel.name} features")
        if not (np.isfinite(self.std).all() and (self.std > 0).all()):
            raise MlctError("std must be finite and > 0 everywhere (normalization divides by it)")

        self.skipped: list[str] = []  # messages of the bad files skipped
        self.filtered = 0  # motions and sub-clips dropped by the length filter
        self.items: list[_Item] = []
        for name in self.layout.read_split(split):
            try:
                self._add(name)
            except BadFileError as error:
                if on_bad_file == "strict":
                    raise MlctError(f"{error} (pass on_bad_file='skip' to skip bad files; "
                                    f"`mlct data check` lists them all)") from None
                self.skipped.append(str(error))
        if self.skipped:
            warnings.warn(f"skipped {len(self.skipped)} bad file(s) in {self.layout.root} "
                          f"split {split!r}, first: {self.skipped[0]}", stacklevel=2)
        if not self.items:
            raise MlctError(f"{self.layout.split_path(split)}: no motion within the length "
                            f"filter {skel.min_frames}..{skel.max_frames - 1} frames")

        if generator is None:
            generator = torch.Generator()
            if seed is None:
                generator.seed()  # fresh entropy: nondeterministic unless a seed is given
            else:
                generator.manual_seed(seed)
        self.generator = generator
        self._worker_rng: tuple[int, torch.Generator] | None = None

    def _add(self, name: str) -> None:
        """Load one motion and its captions into items (raises BadFileError)."""
        motion = self.layout.load_features(name, self.skeleton)
        captions = self.layout.read_texts(name)
        motion = (motion - self.mean) / self.std  # normalize once; sub-clips are views
        whole = []
        for number, record in enumerate(captions, start=1):
            span = record.frame_span(self.skeleton.fps)
            if span is None:
                whole.append(record)
                continue
            clip = motion[span[0]:span[1]]
            if self._in_range(len(clip)):
                self.items.append(_Item(f"{name}#{number}", clip, (record,)))
            else:
                self.filtered += 1
        if whole:
            if self._in_range(len(motion)):
                self.items.append(_Item(name, motion, tuple(whole)))
            else:
                self.filtered += 1

    def _in_range(self, frames: int) -> bool:
        return self.skeleton.min_frames <= frames < self.skeleton.max_frames

    def __len__(self) -> int:
        return len(self.items)

    def name(self, index: int) -> str:
        """The item's name: the motion's, or `NAME#LINE` for the sub-clip of caption line LINE."""
        return self.items[index].name

    @property
    def lengths(self) -> np.ndarray:
        """(N,) frame counts of the items before cropping."""
        return np.array([len(item.motion) for item in self.items])

    def _rng(self) -> torch.Generator:
        """The dataset's generator, or in a DataLoader worker one seeded by the worker's seed."""
        info = get_worker_info()
        if info is None:
            return self.generator
        # Each worker holds a copy of the dataset: reseed it from the worker seed (which the
        # DataLoader derives from its own generator) so workers do not repeat each other.
        if self._worker_rng is None or self._worker_rng[0] != info.seed:
            generator = torch.Generator()
            generator.manual_seed(info.seed)
            self._worker_rng = (info.seed, generator)
        return self._worker_rng[1]

    def _randint(self, low: int, high: int, rng: torch.Generator | None = None) -> int:
        """Uniform integer in [low, high] from `rng`, else the dataset's generator."""
        return int(torch.randint(low, high + 1, (1,), generator=rng or self._rng()).item())

    def crop_length(self, frames: int, rng: torch.Generator | None = None) -> int:
        """The random crop length: a multiple of unit_length, one unit shorter 1/3 of the time."""
        units = frames // self.unit_length
        # The reference: coin in ['single', 'single', 'double'] when unit_length < 10.
        if self.unit_length < 10 and self._randint(0, 2, rng) == 2:
            units -= 1
        units = min(units, self.max_motion_length // self.unit_length)
        return max(units, 1) * self.unit_length

    def _sample(self, index: int, rng: torch.Generator | None = None
                ) -> tuple[TextRecord, torch.Tensor, int]:
        """A random caption of item `index` and a random crop, padded: (record, motion, length)."""
        record, start, length = self.choose(index, rng)
        item = self.items[index]
        motion = torch.zeros(self.max_motion_length, item.motion.shape[1], dtype=torch.float32)
        motion[:length] = torch.from_numpy(item.motion[start:start + length])
        return record, motion, length

    def choose(self, index: int, rng: torch.Generator | None = None
               ) -> tuple[TextRecord, int, int]:
        """What `_sample` draws for item `index`, without copying the motion: (caption record,
        first frame, length of the crop). A trainer holding the motions on its device gathers
        the crop there (train/resident.py) from these three."""
        item = self.items[index]
        record = item.captions[self._randint(0, len(item.captions) - 1, rng)]
        length = min(self.crop_length(len(item.motion), rng), len(item.motion))
        start = self._randint(0, len(item.motion) - length, rng)
        return record, start, length

    def __getitem__(self, index: int) -> Sample:
        record, motion, length = self._sample(index)
        return Sample(record.caption, list(record.tokens), motion, length)

    def sample(self, index: int, generator: torch.Generator) -> Sample:
        """Item `index` with its caption and crop drawn from `generator`: the same generator
        state gives the same sample in any process (the trainer's exact resume relies on it)."""
        record, motion, length = self._sample(index, generator)
        return Sample(record.caption, list(record.tokens), motion, length)

    def captions(self) -> list[str]:
        """Every caption of the split, each once, in a stable order (for text-embedding caches)."""
        return sorted({record.caption for item in self.items for record in item.captions})

    def denormalize(self, motion: torch.Tensor | np.ndarray) -> torch.Tensor | np.ndarray:
        """Undo the Mean/Std normalization (the reference's inv_transform)."""
        if isinstance(motion, torch.Tensor):
            return motion * torch.as_tensor(self.std, dtype=motion.dtype, device=motion.device) \
                + torch.as_tensor(self.mean, dtype=motion.dtype, device=motion.device)
        return motion * self.std + self.mean


class Text2MotionEvalDataset(Text2MotionDataset):
    """The evaluation variant: tokens framed as the evaluator's text encoder expects.

    As Text2MotionDatasetV2's evaluation output: `sos/OTHER` + at most max_text_length tokens +
    `eos/OTHER`, padded with `unk/OTHER` to max_text_length + 2; sent_len is the framed length.
    Pass the evaluator's mean/std when it was trained with its own normalization.
    """

    def __init__(self, root: str | os.PathLike, split: str = "test", *,
                 max_text_length: int = MAX_TEXT_LENGTH, **kwargs: Any) -> None:
        super().__init__(root, split, **kwargs)
        self.max_text_length = max_text_length

    def __getitem__(self, index: int) -> EvalSample:  # type: ignore[override]
        record, motion, length = self._sample(index)
        tokens = ["sos/OTHER", *record.tokens[: self.max_text_length], "eos/OTHER"]
        sent_len = len(tokens)
        tokens += ["unk/OTHER"] * (self.max_text_length + 2 - sent_len)
        return EvalSample(record.caption, tokens, motion, length, sent_len)


def collate(batch: Sequence[Sample | EvalSample]) -> dict[str, Any]:
    """Stack samples: captions and tokens as lists, motion (B, L, D), length (B,) (+ sent_len).

    Evaluation batches (EvalSample) are sorted by sent_len, longest first, as the reference's
    collate_fn does for the evaluator's packed GRU.
    """
    if batch and isinstance(batch[0], EvalSample):
        batch = sorted(batch, key=lambda sample: sample.sent_len, reverse=True)
    out: dict[str, Any] = {
        "caption": [sample.caption for sample in batch],
        "tokens": [sample.tokens for sample in batch],
        "motion": torch.stack([sample.motion for sample in batch]),
        "length": torch.tensor([sample.length for sample in batch], dtype=torch.long),
    }
    if batch and isinstance(batch[0], EvalSample):
        out["sent_len"] = torch.tensor([s.sent_len for s in batch], dtype=torch.long)
    return out
