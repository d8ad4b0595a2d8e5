"""The Bandai Namco Research motion dataset: two sets of BVH clips by professional actors, at
30 fps in centimetres, each clip one content (walk, bow, kick, ...) in one style (tired, proud,
childish, ...), both said in its file name: `dataset-1_walk-back_tired_001.bvh`.

Source: github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset. License:
CC BY-NC 4.0, non-commercial use only; cite Kobayashi et al., "Motion Capture Dataset for
Practical Use of AI-based Motion Editing and Stylization", arXiv:2306.08861, 2023.

Its rig maps one to one onto HumanML3D's joints but for spine3: SMPL has three spine joints
where the rig has Spine and Chest, so spine3 is placed halfway from Chest to Neck, below the
collars, which the rig hangs off its chest 13 cm up. The clips start and end at rest; the
length filter drops those under 2 s (the import lists them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mlct.data.corpora.base import Corpus, RealClip
from mlct.data.corpora.wording import NO_STYLE, Style, captions
from mlct.data.importer import Between
from mlct.errors import MlctError

_SIDES = ("left", "right")
JOINT_MAP = {"Hips": "pelvis", "Spine": "spine1", "Chest": "spine2", "Neck": "neck",
             "Head": "head",
             **{f"{part}_{s[0].upper()}": f"{s}_{ours}" for s in _SIDES for part, ours in (
                 ("Shoulder", "collar"), ("UpperArm", "shoulder"), ("LowerArm", "elbow"),
                 ("Hand", "wrist"), ("UpperLeg", "hip"), ("LowerLeg", "knee"),
                 ("Foot", "ankle"), ("Toes", "foot"))}}
BETWEEN = {"spine3": (Between("Chest", "Neck", 0.5),)}

# What each content is, in a few wordings (<verb> marks, HIS: wording.py). The dataset's own
# videos and a filmstrip of every content were looked at to say it right (docs/data.md).
CONTENTS: dict[str, tuple[str, ...]] = {
    "walk": ("<walk> forward", "<walk> straight ahead", "<take> a few steps forward",
             "<walk> ahead"),
    "walk-back": ("<walk> backward", "<walk> backwards", "<take> a few steps backward"),
    "walk-left": ("<walk> to the left", "<walk> towards HIS left", "<walk> leftward"),
    "walk-right": ("<walk> to the right", "<walk> towards HIS right", "<walk> rightward"),
    "walk-turn-left": ("<walk> forward and <turn> left", "<walk> and <turn> to the left",
                       "<walk> in a curve to the left"),
    "walk-turn-right": ("<walk> forward and <turn> right", "<walk> and <turn> to the right",
                        "<walk> in a curve to the right"),
    "run": ("<run> forward", "<run> straight ahead", "<jog> forward"),
    "dash": ("<sprint> forward", "<dash> forward", "<run> forward as fast as possible"),
    "bow": ("<bow>", "<bow> politely", "<give> a bow", "<bow> forward"),
    "bye": ("<wave> goodbye", "<wave> goodbye with one hand", "<wave> a hand to say goodbye"),
    "byebye": ("<wave> goodbye with both hands", "<wave> both hands to say goodbye",
               "<wave> goodbye eagerly"),
    "call": ("<lean> forward and <call> out with HIS hands around HIS mouth",
             "<shout> to someone far away, hands cupped around HIS mouth",
             "<call> out to someone, leaning forward"),
    "guide": ("<show> the way with a hand", "<gesture> the way", "<point> the way to go"),
    "respond": ("<raise> a hand to answer", "<answer> with a raised hand",
                "<raise> a hand in reply"),
    "punch": ("<punch>", "<throw> a punch", "<punch> forward"),
    "kick": ("<kick>", "<kick> forward", "<kick> with one leg"),
    "slash": ("<slash> with a sword", "<swing> a sword", "<slash> forward with a blade"),
    "dance-short": ("<dance>", "<dance> briefly", "<do> a short dance"),
    "dance-long": ("<dance>", "<dance> for a while", "<do> a dance"),
    "wave-both-hands": ("<wave> both hands", "<wave> with both hands", "<wave> both arms"),
    "wave-left-hand": ("<wave> HIS left hand", "<wave> with the left hand",
                       "<wave> with HIS left hand"),
    "wave-right-hand": ("<wave> HIS right hand", "<wave> with the right hand",
                        "<wave> with HIS right hand"),
    "raise-up-both-hands": ("<raise> both hands", "<raise> both arms up", "<lift> both hands"),
    "raise-up-left-hand": ("<raise> HIS left hand", "<raise> the left arm up",
                           "<lift> HIS left hand"),
    "raise-up-right-hand": ("<raise> HIS right hand", "<raise> the right arm up",
                            "<lift> HIS right hand"),
}

STYLES: dict[str, Style] = {
    "normal": NO_STYLE,
    "happy": Style(("happy", "cheerful"), ("happily", "cheerfully")),
    "sad": Style(("sad", "gloomy"), ("sadly", "looking sad")),
    "angry": Style(("angry", "furious"), ("angrily", "looking angry")),
    "proud": Style(("proud",), ("proudly", "with pride")),
    "not-confident": Style(("timid", "shy"), ("timidly", "without confidence")),
    "masculinity": Style((), ("in a masculine way", "in a manly way")),
    "masculine": Style((), ("in a masculine way", "in a manly way")),
    "feminine": Style((), ("in a feminine way", "in a ladylike way")),
    "childish": Style(("childish",), ("like a child", "in a childish way")),
    "youthful": Style(("young", "youthful"), ("in a youthful way", "with youthful energy")),
    "old": Style(("old", "elderly"), ("like an old person", "like an elderly person")),
    "elderly": Style(("old", "elderly"), ("like an old person", "like an elderly person")),
    "tired": Style(("tired", "weary"), ("wearily", "as if tired")),
    "exhausted": Style(("exhausted", "worn-out"), ("as if exhausted", "wearily")),
    "active": Style(("energetic", "lively"), ("energetically", "with energy")),
    "musical": Style((), ("theatrically", "as in a musical")),
    "giant": Style((), ("heavily, like a giant", "like a giant")),
    "chimpira": Style((), ("like a thug", "with a swagger", "like a street punk")),
}
CAPTIONS_PER_CLIP = 4


def find_clips(root: Path) -> list[RealClip]:
    """Every `dataset-N_CONTENT_STYLE_ID.bvh` under `root` (the repository or its dataset/)."""
    clips = []
    for path in sorted(root.rglob("dataset-*_*.bvh")):
        parts = path.stem.split("_")
        if len(parts) != 4:
            raise MlctError(f"{path}: not a Bandai Namco clip name "
                            f"(dataset-N_CONTENT_STYLE_ID.bvh)")
        subset, content, style, take = parts
        if content not in CONTENTS or style not in STYLES:
            raise MlctError(f"{path}: unknown content {content!r} or style {style!r}")
        clips.append(RealClip(name=path.stem, path=path,
                              labels={"content": content, "style": style,
                                      "subset": subset, "take": take}))
    if not clips:
        raise MlctError(f"{root}: no Bandai Namco clips (dataset-N_CONTENT_STYLE_ID.bvh) in it")
    return clips


def caption_clip(labels: dict[str, Any], rng: Any, count: int) -> list[str]:
    return captions(CONTENTS[labels["content"]], STYLES[labels["style"]], rng, count)


BANDAI_NAMCO = Corpus(
    name="bandai-namco", title="Bandai Namco Research Motion Dataset",
    license="CC BY-NC 4.0", commercial=False,
    citation="Kobayashi et al., Motion Capture Dataset for Practical Use of AI-based Motion "
             "Editing and Stylization, arXiv:2306.08861, 2023",
    url="https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset",
    joint_map=JOINT_MAP, between=BETWEEN, scale=0.01, find=find_clips, caption=caption_clip)
