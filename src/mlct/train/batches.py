"""Deterministic, resumable batches: the batch of step k is a pure function of (seed, k).

Each epoch is a permutation drawn from (seed, epoch); each item's caption and crop come from a
generator seeded by (seed, step, position in the global batch). So resuming at step k replays
exactly what an uninterrupted run would have seen, whatever the number of DataLoader workers,
and a DDP rank takes its slice of the same global batch.
"""

from __future__ import annotations

from typing import Iterator

import torch
from torch.utils.data import DataLoader, Dataset, Sampler

from mlct.data.dataset import Sample, Text2MotionDataset, collate

_MIX = 1_000_003  # spreads (seed, step, position) over distinct generator seeds


def _seeded(item_seed: int) -> torch.Generator:
    """The generator an item's caption and crop are drawn from."""
    generator = torch.Generator()
    generator.manual_seed(item_seed)
    return generator


class _SeededItems(Dataset):
    """Items addressed by (index, item_seed): the dataset samples with that seed."""

    def __init__(self, dataset: Text2MotionDataset) -> None:
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, key: tuple[int, int]) -> Sample:
        index, item_seed = key
        return self.dataset.sample(index, _seeded(item_seed))


class _SeededChoices(_SeededItems):
    """The same draws as _SeededItems, without the motion: for a trainer that holds the motions
    on its device (train/resident.py) and gathers each crop there."""

    def __getitem__(self, key: tuple[int, int]) -> tuple[str, int, int, int]:
        index, item_seed = key
        record, start, length = self.dataset.choose(index, _seeded(item_seed))
        return record.caption, index, start, length


def collate_choices(choices: list[tuple[str, int, int, int]]) -> dict:
    """Captions as a list; item index, first frame and length as (B,) long tensors."""
    captions, index, start, length = zip(*choices)
    return {"caption": list(captions), "index": torch.tensor(index, dtype=torch.long),
            "start": torch.tensor(start, dtype=torch.long),
            "length": torch.tensor(length, dtype=torch.long)}


class StepBatches(Sampler[list[tuple[int, int]]]):
    """Yields, for steps start..stop-1, this rank's share of each global batch."""

    def __init__(self, size: int, batch_size: int, seed: int, start: int, stop: int,
                 rank: int = 0, world: int = 1) -> None:
        if batch_size % world:
            raise ValueError(f"batch size {batch_size} does not split over {world} processes")
        self.size, self.batch_size, self.seed = size, batch_size, seed
        self.start, self.stop, self.rank, self.world = start, stop, rank, world
        self._epoch_cache: tuple[int, torch.Tensor] | None = None

    def _permutation(self, epoch: int) -> torch.Tensor:
        if self._epoch_cache is None or self._epoch_cache[0] != epoch:
            generator = torch.Generator()
            generator.manual_seed(self.seed * _MIX + epoch)
            self._epoch_cache = (epoch, torch.randperm(self.size, generator=generator))
        return self._epoch_cache[1]

    def global_batch(self, step: int) -> list[tuple[int, int]]:
        """The (index, item_seed) pairs of the whole batch of `step`, over all ranks."""
        out = []
        for position in range(self.batch_size):
            flat = step * self.batch_size + position  # epochs chain without dropping items
            epoch, offset = divmod(flat, self.size)
            index = int(self._permutation(epoch)[offset])
            out.append((index, (self.seed * _MIX + step) * _MIX + position))
        return out

    def __iter__(self) -> Iterator[list[tuple[int, int]]]:
        share = self.batch_size // self.world
        for step in range(self.start, self.stop):
            batch = self.global_batch(step)
            yield batch[self.rank * share:(self.rank + 1) * share]

    def __len__(self) -> int:
        return max(0, self.stop - self.start)


def step_loader(dataset: Text2MotionDataset, batch_size: int, seed: int, start: int, stop: int,
                rank: int = 0, world: int = 1, num_workers: int = 0,
                choices_only: bool = False) -> DataLoader:
    """A DataLoader over steps start..stop-1 of the deterministic batch sequence.

    choices_only: each batch holds what was drawn (caption, item index, first frame, length;
    collate_choices), not the motions: the same batches, for motions kept on the device."""
    sampler = StepBatches(len(dataset), batch_size, seed, start, stop, rank, world)
    # Its own generator: a DataLoader otherwise draws its worker base seed from the global RNG,
    # which would shift the training noise stream on resume.
    generator = torch.Generator()
    generator.manual_seed(seed)
    items, collate_fn = ((_SeededChoices(dataset), collate_choices) if choices_only
                         else (_SeededItems(dataset), collate))
    return DataLoader(items, batch_sampler=sampler, collate_fn=collate_fn,
                      num_workers=num_workers, generator=generator)


def fixed_batches(dataset: Text2MotionDataset, batch_size: int, count: int,
                  seed: int = 12345) -> list[dict]:
    """`count` batches that never change (the validation set of a run)."""
    sampler = StepBatches(len(dataset), batch_size, seed, 0, count)
    items = _SeededItems(dataset)
    return [collate([items[key] for key in keys]) for keys in sampler]
