"""Captions of real clips from their labels: what is done (a content phrase), how (a style) and
which way, in several wordings each, with the procedural benchmark's sentence machinery
(mlct.data.synth.text: <verb> marks conjugated, HIS for the subject's possessive).

Each caption says only what the label says. A style is said one of three ways: as the
subject's adjective ("a tired man walks forward"), as an adverb phrase at the end ("a man
walks forward wearily") or after a comma ("a man walks forward, like an old man"); "normal"
adds no words. A content phrase is one of a few wordings of the same action.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

from mlct.data.synth.colloquial import FORMS as _BENCHMARK_FORMS
from mlct.data.synth.text import _SUBJECTS, Rng, _pick, _render

# Verbs the benchmark's vocabularies lack, with (third person, gerund).
_NEW_VERBS = {
    "dance": ("dances", "dancing"), "slash": ("slashes", "slashing"),
    "beckon": ("beckons", "beckoning"), "gesture": ("gestures", "gesturing"),
    "point": ("points", "pointing"), "nod": ("nods", "nodding"),
    "answer": ("answers", "answering"), "call": ("calls", "calling"),
    "show": ("shows", "showing"), "hack": ("hacks", "hacking"), "cut": ("cuts", "cutting"),
    "groove": ("grooves", "grooving"), "climb": ("climbs", "climbing"),
    "play": ("plays", "playing"), "pick": ("picks", "picking"), "sweep": ("sweeps", "sweeping"),
    "shake": ("shakes", "shaking"), "fall": ("falls", "falling"),
    "lie": ("lies", "lying"), "crawl": ("crawls", "crawling"), "roll": ("rolls", "rolling"),
    "wipe": ("wipes", "wiping"), "wash": ("washes", "washing"), "drink": ("drinks", "drinking"),
    "carry": ("carries", "carrying"), "push": ("pushes", "pushing"), "pull": ("pulls", "pulling"),
    "dribble": ("dribbles", "dribbling"), "shoot": ("shoots", "shooting"),
    "direct": ("directs", "directing"), "sway": ("sways", "swaying"),
    "shout": ("shouts", "shouting"), "stop": ("stops", "stopping"),
    "start": ("starts", "starting"), "fence": ("fences", "fencing"),
    "laugh": ("laughs", "laughing"), "fight": ("fights", "fighting"),
    "duck": ("ducks", "ducking"), "block": ("blocks", "blocking"),
}
FORMS = {**_BENCHMARK_FORMS, **_NEW_VERBS}



@dataclass(frozen=True)
class Style:
    """How a style label is said: adjectives of the subject and adverb phrases."""

    adjectives: tuple[str, ...] = ()
    adverbs: tuple[str, ...] = ()


NO_STYLE = Style()
_VOWEL = re.compile(r"^(a|an) ([aeiou])", re.IGNORECASE)
_CONSONANT = re.compile(r"^an ([^aeiou])", re.IGNORECASE)


def _article(text: str) -> str:
    """'a old man' -> 'an old man', 'an tired man' -> 'a tired man' (the sentence's start)."""
    text = _VOWEL.sub(lambda m: f"an {m.group(2)}", text)
    return _CONSONANT.sub(lambda m: f"a {m.group(1)}", text)


def _with_adjective(subject: str, adjective: str) -> str:
    """'a person' + 'tired' -> 'a tired person'; 'someone' -> 'someone tired'."""
    words = subject.split(" ", 1)
    if len(words) == 1:
        return f"{subject} {adjective}"
    return _article(f"{words[0]} {adjective} {words[1]}")


def caption(phrases: Sequence[str], style: Style, rng: Rng) -> str:
    """One sentence: a subject, one of `phrases` (<verb> marks, HIS) and the style in one of
    its forms."""
    subject, possessive = _pick(rng, _SUBJECTS)
    phrase = _render(_pick(rng, phrases), rng.random() < 0.15, FORMS)
    progressive = phrase.split(" ", 1)[0].endswith("ing")
    forms = ["plain"] if not (style.adjectives or style.adverbs) else []
    if style.adjectives:
        forms.append("adjective")
    if style.adverbs:
        forms += ["adverb", "comma"]
    form = _pick(rng, forms)
    if form == "adjective":
        subject = _with_adjective(subject, _pick(rng, style.adjectives))
    text = f"{subject} is {phrase}" if progressive else f"{subject} {phrase}"
    if form == "adverb":
        text += " " + _pick(rng, style.adverbs)
    elif form == "comma":
        text += ", " + _pick(rng, style.adverbs)
    return text.replace("HIS", possessive) + "."


def captions(phrases: Sequence[str], style: Style, rng: Rng, count: int) -> list[str]:
    """`count` distinct captions (fewer only if the wordings run out)."""
    found: list[str] = []
    for _ in range(40 * count):
        text = caption(phrases, style, rng)
        if text not in found:
            found.append(text)
            if len(found) == count:
                break
    return found
