"""What a real motion-capture corpus tells its importer: where its clips are, what each shows,
how its rig maps onto the skeleton, and whose data it is (license and citation).

A corpus importer finds the clips in the folder a user downloaded, turns each clip's labels
into captions (wording.py) and hands everything to `import_dataset`, which does the processing
of every import (resampling, windows, retargeting, floor and facing, features, splits). Every
motion keeps its provenance: the corpus, the source file, its window of it, the license.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from mlct.data.importer import Between


@dataclass(frozen=True)
class RealClip:
    """One source file of a corpus, with the labels its captions are made from."""

    name: str  # the motion name in the dataset (the window suffix is added for long clips)
    path: Path
    labels: dict[str, Any]  # e.g. {"content": "walk", "style": "tired"}


@dataclass(frozen=True)
class Corpus:
    """A real corpus: how to find its clips and caption them, and the facts of its license."""

    name: str  # the command-line name, e.g. "bandai-namco"
    title: str
    license: str
    commercial: bool  # whether the license allows commercial use
    citation: str
    url: str
    # BVH joint -> skeleton joint; several maps where the corpus's files use several namings
    joint_map: dict[str, str] | tuple[dict[str, str], ...]
    scale: float  # file units -> metres
    find: Callable[[Path], list[RealClip]]
    caption: Callable[[dict[str, Any], Any, int], list[str]]  # labels, rng, count -> captions
    between: dict[str, tuple[Between, ...]] = field(default_factory=dict)
    # path -> a clip (joint_names, positions, fps) for files that are neither BVH nor AMC
    read: Callable[[Path], Any] | None = None

    def provenance(self, clip: RealClip, root: Path) -> dict[str, Any]:
        """The record every motion of `clip` carries in provenance.jsonl."""
        return {"corpus": self.name, "source": self.title,
                "file": clip.path.relative_to(root).as_posix(), "labels": clip.labels,
                "license": self.license, "commercial_use": self.commercial,
                "citation": self.citation}
