"""Captions in the standard layout's text-line format, and their part-of-speech tokens.

One owner for the format of texts/NAME.txt (HumanML3D's): one caption a line,
`caption#word/POS word/POS ...#start#end`, start and end in seconds (0.0#0.0: the whole clip).
`parse_text_line` reads a line, `format_text_line` writes one, `caption_field` takes the caption
of a line without judging the rest (a title is a nicety), and the tagger makes the tokens:
`pos_tag` for the benchmark's closed vocabulary, `tag_caption` for any caption (suffix rules for
words outside it); the synthetic benchmark (data/synth/) and the importer (data/importer.py)
both write through these.

Tokens follow HumanML3D's text_process.py (spaCy en_core_web_sm): hyphens removed, tokens that
are not purely alphabetic dropped (so "90" and "2" vanish from the tokens, as they do there),
only NOUN and VERB tokens lemmatized, and "left" never lemmatized. The benchmark's vocabulary is
closed, so a lexicon plus three context rules replaces spaCy.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

# the words of benchmark version 4's families (they import nothing that imports this module)
from mlct.data.synth import families_arms, families_body

SEPARATOR = "#"  # between the four fields of a line


class TextLineError(ValueError):
    """A text line that breaks the `caption#tokens#start#end` format (message without location)."""


@dataclass(frozen=True)
class TextRecord:
    """One caption line: the caption, its word/POS tokens and the annotated span in seconds."""

    caption: str
    tokens: tuple[str, ...]
    start: float
    end: float

    @property
    def whole_clip(self) -> bool:
        """True when the caption describes the whole motion (`0.0#0.0`)."""
        return self.start == 0.0 and self.end == 0.0

    @property
    def words(self) -> tuple[str, ...]:
        """The words of the tokens, without their POS tags."""
        return tuple(token.rsplit("/", 1)[0] for token in self.tokens)

    def frame_span(self, fps: float) -> tuple[int, int] | None:
        """[begin, end) frames of the sub-clip at `fps`, or None for the whole clip."""
        if self.whole_clip:
            return None
        # int() truncates, as the reference's `motion[int(f_tag*20):int(to_tag*20)]`.
        return int(self.start * fps), int(self.end * fps)


def parse_text_line(line: str) -> TextRecord:
    """Parse one `caption#word/POS ...#start#end` line; raise TextLineError if ill-formed."""
    line = line.strip()
    if not line:
        raise TextLineError("empty line")
    fields = line.split(SEPARATOR)
    if len(fields) != 4:
        raise TextLineError(f"expected 4 '#'-separated fields (caption#tokens#start#end), "
                            f"found {len(fields)}")
    caption, token_field, start_text, end_text = (field.strip() for field in fields)
    if not caption:
        raise TextLineError("empty caption")
    tokens = tuple(token_field.split())
    if not tokens:
        raise TextLineError("no word/POS tokens")
    for token in tokens:
        word, slash, pos = token.rpartition("/")
        if not slash or not word or not pos:
            raise TextLineError(f"token {token!r} is not word/POS")
    start = _parse_time(start_text, "start")
    end = _parse_time(end_text, "end")
    if not (start == 0.0 and end == 0.0) and end <= start:
        raise TextLineError(f"end {end:g} s is not after start {start:g} s")
    return TextRecord(caption=caption, tokens=tokens, start=start, end=end)


def _parse_time(text: str, what: str) -> float:
    """A start/end time in seconds; nan means 0.0 as in the reference."""
    try:
        value = float(text)
    except ValueError:
        raise TextLineError(f"{what} time {text!r} is not a number") from None
    if math.isnan(value):
        return 0.0  # the reference maps nan to 0.0 (= whole clip when both are)
    if math.isinf(value) or value < 0:
        raise TextLineError(f"{what} time {text!r} is not a finite time >= 0")
    return value


def caption_field(line: str) -> str:
    """The caption of a text line (its first field), stripped; the rest is not checked."""
    return line.split(SEPARATOR, 1)[0].strip()


# ---------------------------------------------------------------------------------------------
# Verbs: lemma -> (third person singular, gerund); the synthetic captions conjugate with them.
# ---------------------------------------------------------------------------------------------

# The verbs of the lexicon (the benchmark's captions use no others), with their forms.
VERBS = (
    "walk stroll pace move hurry jog run dash back step sidestep shuffle take turn rotate pivot "
    "make circle jump leap do hop balance squat crouch bend stand sit get rise wave raise lift "
    "put clap punch throw jab kick bow give straighten stretch lean reach spin kneel go drop "
    "stay wait pause "
    # the families of benchmark version 3
    "lie pick touch point salute place rest cross fold nod march perform lunge"
).split()
_DOUBLE_FINAL = frozenset(
    "jog run step sidestep hop squat sit get put clap spin drop jab nod".split())
_IRREGULAR = {"lie": ("lies", "lying")}


def _third_person(lemma: str) -> str:
    if lemma.endswith(("s", "sh", "ch", "x", "z", "o")):
        return lemma + "es"
    if lemma.endswith("y") and lemma[-2] not in "aeiou":
        return lemma[:-1] + "ies"
    return lemma + "s"


def _gerund(lemma: str) -> str:
    if lemma in _DOUBLE_FINAL:
        return lemma + lemma[-1] + "ing"
    if lemma.endswith("e") and not lemma.endswith("ee"):
        return lemma[:-1] + "ing"
    return lemma + "ing"


VERB_FORMS = {v: _IRREGULAR.get(v, (_third_person(v), _gerund(v))) for v in VERBS}
# the families of benchmark version 4, each module's own (synth/families_arms.py's interface)
_VERSION_4_MODULES = (families_body, families_arms)
for _module in _VERSION_4_MODULES:
    VERB_FORMS.update(_module.VERBS["benchmark"])


# ---------------------------------------------------------------------------------------------
# Tokens as HumanML3D stores them: word -> (lemma, Universal POS) plus three context rules.
# ---------------------------------------------------------------------------------------------

_POS_WORDS = {
    "DET": "a an the both all his her their",
    "PRON": "someone that something",
    "NOUN": "person man woman figure human hand arm leg foot knee fist shoulder head chest waist "
            "side place spot air pace line reverse chair seat moment degree time way front quarter "
            "floor ground object toe hip forehead jack",
    "ADJ": "slow normal steady leisurely brisk invisible imaginary single slight sharp deep "
           "full half same idle motionless other raised crossed",
    "ADV": "forward backward backwards straight fast ahead sideways around back forth together "
           "again briefly politely high upward overhead there still quietly slightly sharply once "
           "twice then first finally slowly quickly briskly rapidly counterclockwise clockwise "
           "left right flat",
    "NUM": "one two three four five forty ninety hundred thirty eighty sixty",
    "ADP": "up down out on in with to by into at of for over above before after from off "
           "across",
    "CCONJ": "and",
    "SCONJ": "while",
    "AUX": "is",
}
_PLURALS = {"hands": "hand", "arms": "arm", "legs": "leg", "feet": "foot", "knees": "knee",
            "times": "time", "degrees": "degree", "toes": "toe", "hips": "hip", "jacks": "jack",
            "pushups": "pushup"}
# Words spaCy reads as a noun after a determiner, number or adjective ("does two squats",
# "a quarter turn") and as a verb elsewhere ("squats twice").
_NOUN_OR_VERB = frozenset(
    "turn kick punch jump squat bow wave step hop circle spin clap jog salute nod point "
    "lunge".split())
# Adjective right before a noun ("his left hand", "a fast pace"), noun after a determiner
# ("to the left"), otherwise the listed tag ("turns left", "walks fast").
_SIDE_WORDS = frozenset(("left", "right"))
_MODIFIERS = frozenset("left right forward straight fast counterclockwise clockwise".split())

_LEXICON: dict[str, tuple[str, str]] = {
    w: (w, pos) for pos, ws in _POS_WORDS.items() for w in ws.split()}
_LEXICON.update({w: (lemma, "NOUN") for w, lemma in _PLURALS.items()})
for _module in _VERSION_4_MODULES:
    _LEXICON.update({w: (w, pos) for w, pos in _module.WORDS.items()})
    _LEXICON.update({w: (lemma, "NOUN") for w, lemma in _module.PLURALS.items()})
for _v, (_s, _g) in VERB_FORMS.items():
    _LEXICON[_s] = _LEXICON[_g] = (_v, "VERB")
for _v in _NOUN_OR_VERB:
    _LEXICON[_v] = (_v, "NOUN")
_NOUN_LIKE = frozenset(w for w, (_, pos) in _LEXICON.items() if pos == "NOUN") | {
    VERB_FORMS[v][0] for v in _NOUN_OR_VERB}
_AMBIGUOUS_NV = _NOUN_OR_VERB | {VERB_FORMS[v][0] for v in _NOUN_OR_VERB}
_TOKEN = re.compile(r"[a-z0-9]+|[^\sa-z0-9]")
POS_TAGS = ("NOUN", "VERB", "ADJ", "ADV", "ADP", "DET", "NUM", "PRON", "CCONJ", "SCONJ", "PART",
            "AUX", "PROPN")


def pos_tag(caption: str) -> list[tuple[str, str]]:
    """(token, POS) pairs as in HumanML3D texts: NOUN/VERB lemmatized, punctuation and numerals
    dropped; ValueError for a word outside the closed vocabulary."""
    words = _TOKEN.findall(caption.lower().replace("-", ""))
    tags: list[str] = []
    for i, w in enumerate(words):
        if w.isdigit():
            tags.append("NUM")  # kept for context, dropped below as HumanML3D drops non-alpha
            continue
        if not w.isalpha():
            tags.append("PUNCT")
            continue
        if w not in _LEXICON:
            raise ValueError(f"word {w!r} in {caption!r} is not in the caption lexicon")
        pos = _LEXICON[w][1]
        prev = tags[-1] if tags else ""
        if w in _MODIFIERS:
            if i + 1 < len(words) and words[i + 1] in _NOUN_LIKE:
                pos = "ADJ"
            elif prev == "DET" and w in _SIDE_WORDS:
                pos = "NOUN"
        elif w in _AMBIGUOUS_NV:
            noun = prev in ("DET", "NUM", "ADJ") or (i > 0 and words[i - 1] == "quarter")
            pos = "NOUN" if noun else "VERB"
        tags.append(pos)
    return [(_LEXICON[w][0] if pos in ("NOUN", "VERB") else w, pos)
            for w, pos in zip(words, tags) if w.isalpha()]


def format_text_line(caption: str, tags: Sequence[tuple[str, str]], start: float = 0.0,
                     end: float = 0.0) -> str:
    """One line of a HumanML3D texts/*.txt file: caption#word/POS ...#start#end."""
    if SEPARATOR in caption or "\n" in caption:
        raise ValueError(f"caption may not contain '#' or a newline: {caption!r}")
    for word, pos in tags:
        if not word.isalpha() or pos not in POS_TAGS:
            raise ValueError(f"bad token {word!r}/{pos!r}")
    tokens = " ".join(f"{w}/{p}" for w, p in tags)
    return SEPARATOR.join((caption, tokens, str(float(start)), str(float(end))))


# ---------------------------------------------------------------------------------------------
# Captions outside the benchmark's lexicon (the importer's): suffix rules per word.
# ---------------------------------------------------------------------------------------------

_WORDS = re.compile(r"[^\W_]+")
# Closed-class words the benchmark's lexicon lacks (its captions never use them).
_FUNCTION_WORDS = {
    **dict.fromkeys("it they them he she him himself herself themselves its this".split(), "PRON"),
    **dict.fromkeys("from through across behind toward towards onto off under like as near "
                    "along against between".split(), "ADP"),
    **dict.fromkeys("these those some another each every".split(), "DET"),
    **dict.fromkeys("or but".split(), "CCONJ"),
    **dict.fromkeys("are was were be been".split(), "AUX"),
    "not": "PART",
}


def tag_caption(caption: str) -> list[tuple[str, str]]:
    """(word, POS) tokens of a caption: the benchmark's tagger, suffix rules for other words."""
    try:
        return pos_tag(caption)
    except ValueError:
        pass  # a word outside the benchmark's lexicon: tag word by word
    tags: list[tuple[str, str]] = []
    for word in _WORDS.findall(caption.lower().replace("-", "")):
        if not word.isalpha():
            continue  # numerals dropped, as HumanML3D drops non-alphabetic tokens
        try:
            tags.extend(pos_tag(word))
        except ValueError:
            tags.append(_guess_tag(word, tags[-1][1] if tags else ""))
    return tags


def _guess_tag(word: str, previous: str) -> tuple[str, str]:
    """(lemma, POS) of a word outside the lexicon, by its suffix and the tag before it."""
    if word in _FUNCTION_WORDS:
        return word, _FUNCTION_WORDS[word]
    if len(word) >= 4 and word.endswith("ly"):
        return word, "ADV"
    if (len(word) >= 6 and word.endswith("ing")) or (
            len(word) >= 5 and word.endswith("ed") and not word.endswith("eed")):
        return word, "VERB"
    if previous in ("NOUN", "PRON", "CCONJ", "ADV") and word.endswith("s") and \
            not word.endswith("ss"):
        # "a person stumbles", "and then tosses": a third-person verb -> its lemma
        if word == "goes" or word.endswith(("ches", "shes", "sses", "xes", "zes")):
            return word[:-2], "VERB"
        return (word[:-3] + "y" if word.endswith("ies") else word[:-1]), "VERB"
    return word, "NOUN"
