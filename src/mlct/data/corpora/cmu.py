"""The CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu): 2,435 takes of 144 subjects,
named `SS_TT` (subject, take), each with a one-line description in CMU's index
(cmu_index.tsv beside this file). Its takes are published as ASF/AMC by CMU and as BVH
conversions by others; this importer reads CMU's ASF/AMC (motion/asf_amc.py, bones named as
in the ASF) and the BVH conversions in three namings: CMU's ASF bone names, CMU's BVH naming
(Hips, LeftHip, ..., Chest2, as in the conversions of subject 131) and the Daz/Poser naming
(hip, abdomen, chest, lThigh, ...), whose feet end in an End Site instead of a toe joint.

CMU's terms: free for research and commercial use; cite mocap.cs.cmu.edu ("The data used in
this project was obtained from mocap.cs.cmu.edu. The database was created with funding from NSF
EIA-0196217.").

The BVH conversions differ in units and body size (some are in inches, some rescaled to a
1.3 m body), so each clip is scaled by its legs (importer.leg_scale). A take is captioned from
its index description through DESCRIPTIONS; takes whose description says nothing a caption can
(calibration, "unknown") or names props the motion leans on (a ladder, playground bars) are left
out and listed.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mlct.data.corpora.base import Corpus, RealClip
from mlct.data.corpora.wording import NO_STYLE, captions
from mlct.data.importer import LEGS, Between
from mlct.errors import MlctError

INDEX_FILE = Path(__file__).with_name("cmu_index.tsv")
_TAKE = re.compile(r"^(\d{2,3})_(\d{2})$")

# CMU's BVH naming (the conversions of subject 131) and the Daz/Poser naming, onto HumanML3D.
_CMU_BVH = {"Hips": "pelvis", "lowerback": "spine1", "Chest": "spine2", "Chest2": "spine3",
            "Neck": "neck", "Head": "head"}
_DAZ = {"hip": "pelvis", "abdomen": "spine1", "chest": "spine2", "neck": "neck",
        "head": "head"}
# CMU's ASF bone names (the BVH conversions call the root "hip", the AMC reader "root"): a joint
# sits where its bone starts, so lowerback is at the root and lowerneck on the thorax with zero
# length (mapping either to a spine joint folds the spine).
_ASF = {"hip": "pelvis", "root": "pelvis", "upperback": "spine1", "thorax": "spine2", "upperneck": "neck",
        "head": "head"}
for _side in ("left", "right"):
    _s, _Side = _side[0], _side.capitalize()
    _CMU_BVH.update({f"{_Side}Hip": f"{_side}_hip", f"{_Side}Knee": f"{_side}_knee",
                     f"{_Side}Ankle": f"{_side}_ankle", f"{_Side}Toe": f"{_side}_foot",
                     f"{_Side}Collar": f"{_side}_collar",
                     f"{_Side}Shoulder": f"{_side}_shoulder",
                     f"{_Side}Elbow": f"{_side}_elbow", f"{_Side}Wrist": f"{_side}_wrist"})
    _DAZ.update({f"{_s}Thigh": f"{_side}_hip", f"{_s}Shin": f"{_side}_knee",
                 f"{_s}Foot": f"{_side}_ankle", f"{_s}Foot.end": f"{_side}_foot",
                 f"{_s}Collar": f"{_side}_collar", f"{_s}Shldr": f"{_side}_shoulder",
                 f"{_s}ForeArm": f"{_side}_elbow", f"{_s}Hand": f"{_side}_wrist"})
    _ASF.update({f"{_s}femur": f"{_side}_hip", f"{_s}tibia": f"{_side}_knee",
                 f"{_s}foot": f"{_side}_ankle", f"{_s}toes": f"{_side}_foot",
                 f"{_s}clavicle": f"{_side}_collar", f"{_s}humerus": f"{_side}_shoulder",
                 f"{_s}radius": f"{_side}_elbow", f"{_s}wrist": f"{_side}_wrist"})
ASF_JOINT_MAP = _ASF  # CMU's bone names, read also by the expmap set (cmu_expmap.py)
JOINT_MAPS = (_CMU_BVH, _DAZ, _ASF)  # one per naming; a file takes the one that fits it
# The Daz and ASF namings have one chest bone where SMPL has spine2 and spine3.
BETWEEN = {"spine3": (Between("chest", "neck", 0.4), Between("thorax", "upperneck", 0.3))}

# CMU index descriptions (lower case) -> what a caption may say of them.
DESCRIPTIONS: dict[str, tuple[str, ...]] = {
    "walk": ("<walk> forward", "<walk> straight ahead", "<walk>"),
    "walk forward": ("<walk> forward", "<walk> straight ahead"),
    "normal walk": ("<walk> forward", "<walk> at a normal pace"),
    "slow walk": ("<walk> forward slowly", "<walk> slowly", "<stroll> slowly forward"),
    "walk slow": ("<walk> forward slowly", "<walk> slowly"),
    "brisk walk": ("<walk> forward briskly", "<walk> quickly", "<walk> at a brisk pace"),
    "walk fast": ("<walk> forward quickly", "<walk> fast"),
    "walk/stride": ("<walk> forward with long strides", "<stride> forward"),
    "slow walk/stride": ("<walk> slowly with long strides", "<stride> slowly forward"),
    "walk, exaggerated stride": ("<walk> with very large steps",
                                 "<walk> forward with exaggerated strides"),
    "walk on uneven terrain": ("<walk> over uneven ground", "<walk> carefully on uneven terrain",
                               "<walk> across bumpy ground"),
    "start walk stop": ("<walk> forward and <stop>", "<start> walking, then <stop>",
                        "<walk> a few steps and <stop>"),
    "start hop stop": ("<hop> around and <stop>", "<start> hopping, then <stop>"),
    "run": ("<run> forward", "<run> straight ahead", "<run>"),
    "run/jog": ("<jog> forward", "<run> forward", "<jog>"),
    "jump": ("<jump>", "<jump> up", "<do> a jump"),
    "forward jump": ("<jump> forward", "<leap> forward", "<do> a jump forward"),
    "jumpforward": ("<jump> forward", "<leap> forward"),
    "jump, balance": ("<jump> and <keep> HIS balance", "<jump>, then <balance>"),
    "jump up to grab, reach for, tiptoe": ("<jump> up to grab something",
                                           "<reach> up high on tiptoe",
                                           "<jump> and <reach> up high"),
    "punch/strike": ("<punch>", "<throw> punches", "<strike> with HIS fists"),
    "boxing": ("<box>", "<throw> punches like a boxer"),
    "bend over, scoop up, rise, lift arm": (
        "<bend> over, <pick> something up and <lift> it high",
        "<pick> something up from the floor and <hold> it up high",
        "<bend> down to scoop something up, then <raise> an arm"),
    "swordplay": ("<fight> with a sword", "<swing> a sword", "<fence> with a sword"),
    "wash self": ("<wash> HIS body", "<wash> HIS body as in a shower"),
    "playground - forward jumps, turn around": (
        "<jump> forward several times, <turn> around and <jump> back",
        "<hop> forward with both feet, then <turn> around"),
    "marching": ("<march> forward", "<march>"),
    "hop on left foot": ("<hop> on HIS left foot", "<hop> on the left leg"),
    "hop on right foot": ("<hop> on HIS right foot", "<hop> on the right leg"),
    "sit on high stool, stand up": ("<sit> down on a high stool and <stand> up",),
    "climb 3 steps": ("<climb> three steps", "<walk> up three steps"),
    "walk forward stepping up stairs": ("<walk> forward and up the stairs",
                                        "<walk> up a flight of stairs"),
    "cartwheel": ("<do> a cartwheel", "<turn> a cartwheel"),
    "soccer - kick ball": ("<kick> a ball", "<kick> a soccer ball"),
    "walk backwards and turn": ("<walk> backwards and <turn>",),
    "laugh": ("<laugh>",),
    "yoga": ("<do> yoga", "<hold> a yoga pose"),
    # subject 131 (Michael Jackson styled motions), 135 (karate) and 5 (modern dance)
    "start duck underneath stop": ("<walk> forward, <duck> under something and <stop>",
                                   "<duck> low under something while walking forward",
                                   "<walk> a few steps, <duck> down and <stop>"),
    "jump stop": ("<jump> forward and <stop>", "<leap> forward, then <stop>"),
    "start walk left": ("<walk> forward, veering to the left", "<walk> off to the left"),
    "start walk right": ("<walk> forward, veering to the right", "<walk> off to the right"),
    "bassai": ("<perform> a karate kata", "<do> a karate form",
               "<perform> a sequence of karate moves"),
    "empi": ("<perform> a karate kata", "<do> a karate form",
             "<perform> a sequence of karate moves"),
    "heiansyodan": ("<perform> a karate kata", "<do> a karate form",
                    "<perform> a sequence of karate moves"),
    "front kick": ("<do> karate front kicks", "<step> forward with front kicks in a karate stance"),
    "mawashigeri": ("<do> karate roundhouse kicks", "<throw> roundhouse kicks"),
    "yokogeri": ("<do> karate side kicks", "<kick> out to the side in a karate stance"),
    "oiduki": ("<step> forward with karate lunge punches", "<do> karate lunge punches",
               "<punch> forward while stepping in a karate stance"),
    "gedanbarai": ("<do> karate low blocks",
                   "<block> downward with HIS forearm in a karate stance"),
    "syutouuke": ("<do> karate knife-hand blocks",
                  "<block> with the edge of HIS hand in a karate stance"),
    "dance - expressive arms, pirouette": ("<dance> with expressive arms and a pirouette",
                                           "<do> a modern dance with a pirouette"),
    "dance - sideways arabesque, turn step, folding arms": (
        "<do> a modern dance with an arabesque and a turn", "<dance> gracefully, turning"),
    "dance - sideways arabesque, folding arms, bending back": (
        "<do> a modern dance with an arabesque, bending back", "<dance> gracefully"),
    "dance - quasi-cou-de-pied, raised leg above hip-height, jete en tourant": (
        "<dance> like a ballet dancer, raising a leg high and leaping while turning",
        "<do> a ballet dance"),
    "dance - small jetes, attitude/arabesque, shifted-axis pirouette, turn": (
        "<do> a ballet dance with small leaps and pirouettes",
        "<dance> like a ballet dancer, leaping and spinning"),
}


def read_index(path: Path = INDEX_FILE) -> dict[str, str]:
    """take -> CMU's description."""
    index = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if line and not line.startswith("#"):
            take, description = line.split("\t", 1)
            index[take] = description
    return index


def find_clips(root: Path) -> list[RealClip]:
    """Every `SS_TT.amc` (with its subject's SS.asf beside it) and `SS_TT.bvh` under `root`
    whose CMU description DESCRIPTIONS can caption; a take found twice is kept once: CMU's own
    AMC before a BVH conversion, else the first path in sorted order."""
    index = read_index()
    clips: dict[str, RealClip] = {}
    amc = [p for p in sorted(root.rglob("*.amc"))
           if p.with_name(p.stem.split("_")[0] + ".asf").is_file()]
    for path in amc + sorted(root.rglob("*.bvh")):
        match = _TAKE.match(path.stem)
        if match is None or path.stem in clips:
            continue
        description = index.get(path.stem)
        if description is None or description.lower() not in DESCRIPTIONS:
            continue
        clips[path.stem] = RealClip(name=f"cmu_{path.stem}", path=path,
                                    labels={"take": path.stem, "description": description,
                                            "subject": int(match.group(1))})
    if not clips:
        raise MlctError(f"{root}: no CMU take (SS_TT.bvh) with a description this importer "
                        f"captions")
    return list(clips.values())


def caption_clip(labels: dict[str, Any], rng: Any, count: int) -> list[str]:
    return captions(DESCRIPTIONS[labels["description"].lower()], NO_STYLE, rng, count)


CMU = Corpus(
    name="cmu", title="CMU Graphics Lab Motion Capture Database",
    license="CMU: free for research and commercial use", commercial=True,
    citation="The data used in this project was obtained from mocap.cs.cmu.edu. The database "
             "was created with funding from NSF EIA-0196217.",
    url="http://mocap.cs.cmu.edu", joint_map=JOINT_MAPS, between=BETWEEN, scale=LEGS,
    find=find_clips, caption=caption_clip)
