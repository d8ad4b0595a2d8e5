"""The CMU motion-prediction set (Li et al., "Convolutional Sequence to Sequence Model for Human
Dynamics", CVPR 2018; published in github.com/chaneyddtt/Convolutional-Sequence-to-Sequence-
Model-for-Human-Dynamics under data/cmu_mocap): takes of the CMU Graphics Lab Motion Capture
Database as exponential maps of one CMU ASF skeleton (motion/cmu_expmap.py reads them), 120 fps,
in eight actions, one folder each: `{train,test}/ACTION/ACTION_N.txt` (walking_extra holds more
walks named walking_N). The files do not name their CMU take; a clip is captioned from its
action, and its provenance names the set's file and, for the sequences in CMU_TAKES, the take.

The data is CMU's: free for research and commercial use; cite mocap.cs.cmu.edu (the text in
cmu.py). The set's skeleton is CMU's bone naming, so the clips map onto the skeleton as CMU's
AMC takes do (cmu.ASF_JOINT_MAP); its thorax has zero length, so spine3 is placed halfway from
the thorax to the upper neck.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mlct.data.corpora.base import Corpus, RealClip
from mlct.data.corpora.cmu import ASF_JOINT_MAP, CMU
from mlct.data.corpora.wording import NO_STYLE, captions
from mlct.data.importer import LEGS, Between
from mlct.errors import MlctError
from mlct.motion.cmu_expmap import read_expmap

_FILE = re.compile(r"^([a-z_]+)_(\d+)$")
_FOLDER_ACTION = {"walking_extra": "walking"}  # the folder of extra walks, its files walking_N

# action (the set's folder) -> what a caption may say of it
ACTIONS: dict[str, tuple[str, ...]] = {
    "walking": ("<walk> forward", "<walk> straight ahead", "<walk>"),
    "running": ("<run> forward", "<run> straight ahead", "<run>"),
    "jumping": ("<jump>", "<jump> several times", "<do> a series of jumps"),
    "soccer": ("<kick> a ball", "<kick> a soccer ball", "<play> soccer"),
    "basketball": ("<dribble> a basketball", "<dribble> a basketball forward",
                   "<dribble> a ball while moving forward"),
    "basketball_signal": ("<make> basketball referee signals",
                          "<signal> like a basketball referee",
                          "<gesture> with HIS arms like a basketball referee"),
    "directing_traffic": ("<direct> traffic with HIS arms", "<direct> traffic",
                          "<wave> cars on like a traffic officer"),
    "washwindow": ("<wash> a window", "<wipe> a window", "<wash> a window with HIS hands"),
}


# Sequences that are CMU takes also published as AMC or BVH (cmu.py): the same frame count to a
# frame and the same pelvis, knee, ankle and wrist curves as the take. Merged with a CMU import
# that has these takes, they would be duplicates.
CMU_TAKES = {
    "train/walking/walking_1": "02_01", "train/walking/walking_2": "05_01",
    "train/walking/walking_3": "06_01", "train/walking/walking_4": "07_01",
    "train/walking/walking_5": "07_02", "train/walking_extra/walking_15": "08_08",
    "train/walking_extra/walking_16": "08_09", "train/walking_extra/walking_18": "10_04",
    "train/walking_extra/walking_19": "12_01", "train/walking_extra/walking_20": "12_02",
    "train/walking_extra/walking_21": "12_03", "train/jumping/jumping_1": "13_11",
    "train/jumping/jumping_4": "13_32", "train/jumping/jumping_5": "13_39",
}


def find_clips(root: Path) -> list[RealClip]:
    """Every `ACTION_N.txt` in an action's folder under `root`, the split (train or test) the set
    put it in taken from the folder above."""
    clips = []
    for path in sorted(root.rglob("*.txt")):
        folder = path.parent.name
        action = _FOLDER_ACTION.get(folder, folder)
        match = _FILE.match(path.stem)
        if action not in ACTIONS or match is None or match.group(1) != action:
            continue
        split = path.parent.parent.name
        labels: dict[str, Any] = {"content": action, "set_split": split,
                                  "sequence": int(match.group(2))}
        take = CMU_TAKES.get(f"{split}/{folder}/{path.stem}")
        if take is not None:
            labels["take"] = take
        clips.append(RealClip(name=f"cmu_expmap_{split}_{folder}_{match.group(2)}", path=path,
                              labels=labels))
    if not clips:
        raise MlctError(f"{root}: no sequence of the CMU expmap set (ACTION/ACTION_N.txt for "
                        f"{', '.join(ACTIONS)})")
    return clips


def caption_clip(labels: dict[str, Any], rng: Any, count: int) -> list[str]:
    return captions(ACTIONS[labels["content"]], NO_STYLE, rng, count)


CMU_EXPMAP = Corpus(
    name="cmu-expmap",
    title="CMU Graphics Lab Motion Capture Database, the motion-prediction set of Li et al. 2018 "
          "(exponential maps)",
    license=CMU.license, commercial=CMU.commercial,
    citation=CMU.citation + " Set as prepared by Li, Zhang, Lee and Lee, Convolutional Sequence "
             "to Sequence Model for Human Dynamics, CVPR 2018.",
    url="https://github.com/chaneyddtt/Convolutional-Sequence-to-Sequence-Model-for-Human-Dynamics",
    joint_map=ASF_JOINT_MAP, between={"spine3": (Between("thorax", "upperneck", 0.5),)},
    scale=LEGS, find=find_clips, caption=caption_clip, read=read_expmap)
