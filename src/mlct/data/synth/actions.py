"""The action vocabulary of the procedural benchmark and the sampling of scripts.

A script is what one motion shows: 1-3 actions in sequence, or a locomotion action with an
upper-body action performed at the same time ("walks forward while waving"). The parameter
values here are the ground truth written to labels.jsonl and described by the captions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mlct.data.synth import families_arms, families_body

# The modules of the families benchmark version 4 adds. Each has the same interface, which this
# module, more_clips.py, the four vocabularies (text.py, everyday.py, colloquial.py, short.py) and
# the caption lexicon (mlct.data.captions) merge; a family module imports none of them:
# - PARAMS: family -> {parameter: its possible values} (FAMILY_PARAMS);
# - CLIPS: family -> clip function (rig, fps, style, **params) -> motions.Clip, as more_clips';
# - PHRASES: vocabulary ("benchmark", "everyday", "colloquial", "short") -> family -> phrase
#   (params, rng) -> str, with the <verb> marks and HIS of text.py and each vocabulary's rules
#   (phrases_more.py);
# - VERBS: vocabulary ("benchmark", "everyday", "colloquial") -> lemma -> (third person,
#   gerund) of the verbs its phrases mark that the vocabulary lacks (the short vocabulary uses
#   the benchmark's);
# - WORDS: word -> part of speech (NOUN, ADJ, ADV, ADP, ...) and PLURALS: plural -> singular,
#   the other words of its benchmark captions that the lexicon lacks;
# - ENDS_DOWN / STARTS_DOWN: families that end on the floor (nothing follows them in a script)
#   and that start lying on the back (first in a script, or right after lying down).
VERSION_4_MODULES = (families_body, families_arms)

# Each family: its parameters and their possible values.
FAMILY_PARAMS: dict[str, dict[str, tuple[Any, ...]]] = {
    "walk": {"speed": ("slow", "normal", "fast"), "direction": ("forward",)},
    "jog": {"direction": ("forward",)},
    "run": {"direction": ("forward",)},
    "walk_backward": {"speed": ("slow", "normal", "fast")},
    "side_step": {"side": ("left", "right"), "steps": (2, 3, 4)},
    "turn": {"side": ("left", "right"), "angle": (45, 90, 135, 180)},
    "circle": {"side": ("left", "right")},
    "jump": {"mode": ("in_place", "forward"), "count": (1, 2, 3)},
    "hop": {"leg": ("left", "right"), "count": (2, 3, 4, 5)},
    "squat": {"count": (1, 2, 3)},
    "sit_stand": {},
    "wave": {"hand": ("left", "right", "both"), "count": (2, 3, 4)},
    "raise_arms": {"hand": ("left", "right", "both")},
    "clap": {"count": (2, 3, 4, 5)},
    "punch": {"hand": ("left", "right"), "count": (1, 2, 3)},
    "kick": {"leg": ("left", "right"), "count": (1, 2)},
    "bow": {},
    "stretch": {},
    "spin": {"side": ("left", "right")},
    "kneel": {"leg": ("left", "right")},
    "stand": {},
    # Added in benchmark version 3: everyday actions without real capture (floor transitions,
    # reaching, exercises, gestures held in place).
    "lie_down": {},
    "get_up": {},
    "sit_floor": {},
    "pick_up": {"hand": ("left", "right", "both")},
    "jumping_jack": {"count": (2, 3, 4)},
    "touch_toes": {},
    "one_leg_stand": {"leg": ("left", "right")},
    "point": {"hand": ("left", "right")},
    "salute": {"hand": ("left", "right")},
    "hands_on_hips": {},
    "cross_arms": {},
    "nod": {"count": (2, 3)},
    "march_in_place": {},
    "push_up": {"count": (2, 3, 4)},
    "lunge": {"leg": ("left", "right"), "count": (2, 3)},
    # Added in benchmark version 4: whole-body and arm families, each module's own.
    **{family: params for module in VERSION_4_MODULES for family, params in module.PARAMS.items()},
}
FAMILIES: tuple[str, ...] = tuple(FAMILY_PARAMS)
# The families each benchmark version samples: versions 1 and 2 have the first 21, and a
# version-2 (version-3) dataset of a seed is remade only if its scripts are drawn from exactly
# these.
FAMILIES_BY_VERSION: dict[int, tuple[str, ...]] = {2: FAMILIES[:21], 3: FAMILIES[:36],
                                                   4: FAMILIES}
NEW_FAMILIES = FAMILIES[21:36]  # the families version 3 adds
NEW_SHARE = 0.3  # of the actions of a version-3 script drawn from the families it adds
VERSION_4_FAMILIES = FAMILIES[36:]
# Of the actions of a version-4 script, drawn from the families it adds; the rest are drawn
# as version 3 draws them.
VERSION_4_SHARE = 0.35
# Floor transitions: a motion that ends lying or sitting on the floor can only go on by
# getting up, and getting up starts lying on the back.
ENDS_DOWN = frozenset({"lie_down", "sit_floor"}).union(
    *(module.ENDS_DOWN for module in VERSION_4_MODULES))
STARTS_DOWN = frozenset({"get_up"}).union(*(module.STARTS_DOWN for module in VERSION_4_MODULES))

LOCOMOTION = ("walk", "walk_backward", "circle", "jog")
UPPER_BODY = ("wave", "raise_arms", "clap", "punch")


@dataclass(frozen=True)
class Action:
    """One action of a script: a family and its parameter values."""

    family: str
    params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.family not in FAMILY_PARAMS:
            raise ValueError(f"unknown action family {self.family!r}")
        spec = FAMILY_PARAMS[self.family]
        for key, value in self.params.items():
            if key not in spec or value not in spec[key]:
                raise ValueError(f"bad parameter {key}={value!r} for {self.family}")

    def to_json(self) -> dict[str, Any]:
        return {"family": self.family, "params": dict(self.params)}


@dataclass(frozen=True)
class Script:
    """What one motion shows: actions in time order, and an optional concurrent upper-body one."""

    actions: tuple[Action, ...]
    concurrent: Action | None = None


def sample_action(rng: np.random.Generator, family: str | None = None) -> Action:
    """A random action (of `family` if given) with uniformly drawn parameters."""
    if family is None:  # version 2's draw: its 21 families, so that its seeds stay as they were
        pool = FAMILIES_BY_VERSION[2]
        family = pool[rng.integers(len(pool))]
    spec = FAMILY_PARAMS[family]
    params = {key: values[rng.integers(len(values))] for key, values in spec.items()}
    return Action(family, params)


def sample_script(rng: np.random.Generator, version: int = 2) -> Script:
    """A random script: mostly single actions, some sequences of 2-3, some 'while' pairs.

    version: of the benchmark (build.VERSIONS). Version 2 draws exactly as it always did;
    version 3 draws NEW_SHARE of its actions from the families it adds; version 4 draws
    VERSION_4_SHARE of them from its own, the rest as version 3."""
    roll = rng.random()
    if roll < 0.12:  # a 'while' pair: locomotion with an upper-body action over it
        base = sample_action(rng, LOCOMOTION[rng.integers(len(LOCOMOTION))])
        upper = sample_action(rng, UPPER_BODY[rng.integers(len(UPPER_BODY))])
        return Script((base,), concurrent=upper)
    count = 1 if roll < 0.55 else 2 if roll < 0.87 else 3
    if version >= 3:
        return _sequence(rng, count, version)
    actions: list[Action] = []
    while len(actions) < count:
        action = sample_action(rng)
        # Standing still is only worth saying on its own or between two actions.
        if action.family == "stand" and count > 1 and len(actions) in (0, count - 1):
            continue
        if actions and actions[-1].family == action.family:
            continue
        actions.append(action)
    return Script(tuple(actions))


def _follows(previous: Action | None, family: str) -> bool:
    """Whether `family` may come right after `previous` (None: first) in a sequence."""
    if previous is not None and previous.family == family:
        return False
    if previous is not None and previous.family in ENDS_DOWN:
        return previous.family == "lie_down" and family == "get_up"
    if family in STARTS_DOWN:
        return previous is None or previous.family == "lie_down"
    return True


def _pool(rng: np.random.Generator, version: int) -> tuple[str, ...]:
    """The families the next action of a version-3 or -4 sequence is drawn from. Version 3's
    draws come first in the stream only for version 3, so its seeds stay as they were."""
    if version >= 4 and VERSION_4_FAMILIES and rng.random() < VERSION_4_SHARE:
        return VERSION_4_FAMILIES
    return NEW_FAMILIES if rng.random() < NEW_SHARE else FAMILIES_BY_VERSION[2]


def _sequence(rng: np.random.Generator, count: int, version: int) -> Script:
    """A sequence of `count` actions of version 3 or 4's families; a floor transition only
    where the body can go on from it (lies down, then gets up)."""
    actions: list[Action] = []
    tries = 0
    while len(actions) < count:
        tries += 1
        if tries > 200:  # a floor ending drawn early leaves no family to follow: start again
            actions, tries = [], 0
        pool = _pool(rng, version)
        action = sample_action(rng, pool[rng.integers(len(pool))])
        if action.family == "stand" and count > 1 and len(actions) in (0, count - 1):
            continue
        if not _follows(actions[-1] if actions else None, action.family):
            continue
        actions.append(action)
    return Script(tuple(actions))
