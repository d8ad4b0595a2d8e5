"""Prompts that name actions one after another: split into one prompt per action.

"a person walks forward, then waves with the right hand" is two motions in a row. The model
draws one action per prompt far better than a sequence in one latent (docs/model_card.md: the
two-action prompts pass 0.00 of their checks as one prompt), and the long-motion chaining
(compose/long_motion.py) already joins prompts into one continuous motion. So the pipeline splits such a
prompt at its sequencing words and chains the parts, each with an equal share of the length.

Words that put the next action after the previous one split: "then", "and then", "after that",
"afterwards"; so do a comma or "and" followed by a verb that starts another action ("claps twice
and jabs with the right arm", "punches, jogs ahead"), but not by one that completes the action
before it ("squats down and stands back up", "raises the arms and bends to one side":
_split_listed). These do not: "while" (two actions at once), "next" (mostly an adjective: "the
next room"), "followed by" (a noun follows: "followed by a bow"). "after"/"before" with a gerund
clause are put in the order of the actions first (in_order: "turns left after walking forward"
is "walks forward, then turns left"). A part without its own subject gets the first part's ("a
person" when none is found), so every part reads like a caption. On the benchmark's test
captions of a sequence, 99.4 % split into as many parts as they name actions (92.8 % before
the comma/"and" rule).

Actions at the same time ("walks forward while waving the right hand", "... and claps at the
same time") are split too when one of the two is an arm action (split_concurrent): the
autoencoder's three latent tokens hold a gait or an arm action, not both (the "+ concurrent"
row of bench/quality.py motion: 0.02 of such motions survive reconstruction), so the body is
made from the rest of the prompt and the arms from the arm action alone, grafted on
(generate/control/fit.py's reattach, a body-part edit).
"""

from __future__ import annotations

import re

from mlct.data.captions import VERB_FORMS as BENCHMARK_FORMS
from mlct.data.synth.everyday import ALL_SUBJECTS

# The verbs the rules know: the benchmark's, and "push" for "pushes herself back up" (a return).
VERB_FORMS = {**BENCHMARK_FORMS, "push": ("pushes", "pushing")}

# The sequencing words, with the punctuation and "and" that may come with them.
_SEQUENCE = re.compile(
    r"\s*(?:[,;.]\s*)?(?:\band\s+)?\b(?:then|after\s+that|afterwards)\b"
    r"\s*,?\s*", re.IGNORECASE)
# A subject: an article and up to seven words before the verb, which ends in "s" but not "ss"
# ("a tired woman sinks", "the old man works", "a person is"; "a little girl in a party dress
# twirls", whose "dress" is not its verb); words of the subject do not ("a boss" may), nor
# are they adverbs ("a person first sits", "a man slowly walks"); else an article and one word
# ("a person walked"), or a pronoun. A word after a determiner is a noun, not the verb ("a fan
# in the stands waves"), and a subject's words may end in "us" or "is" ("a nervous man", "a man
# with his dog"), which no verb does.
_SUBJECT = re.compile(
    r"^(?:(?:a|an|the|this|that)(?:\s+(?!(?:first|then|finally|also|again|now|just|still|"
    r"(?!elderly|lonely|friendly|burly|curly|lovely|jolly|silly|woolly|early|ugly|holy|family)"
    r"[a-z]*ly)\b)"
    r"(?:[a-z]*(?:ss|us|is)|[a-z]*[a-rt-z])){1,7}?"
    r"(?<!\ba)(?<!\ban)(?<!\bthe)(?<!\bhis)(?<!\bher)(?<!\btheir)(?<!\bits)"
    r"(?=\s+(?!(?:his|this)\b)[a-z]*[a-rtv-z]s\b)|"
    r"(?:a|an|the|this|that)\s+[a-z]+|someone|somebody|he|she|they|it|person|man|woman|"
    r"human|figure)\b", re.IGNORECASE)
DEFAULT_SUBJECT = "a person"
MIN_WORDS = 1  # a part must name something to be a prompt of its own


# The subjects the training captions use, and the words of a subject that is a body part ("the
# left arm rises"), which stays.
TRAINED_SUBJECTS = frozenset(subject for subject, _ in ALL_SUBJECTS)
_VERB_HALVES = frozenset("power speed side race tip goose moon back cart hand high long".split())
_BODY_WORDS = frozenset("arm arms hand hands leg legs foot feet knee knees head body torso hip "
                        "hips shoulder shoulders elbow elbows wrist wrists chest back".split())


def plain_subject(text: str) -> str:
    """The text as the model reads it: a subject the training captions never used ("a figure
    skater", "the robot", "a tired woman", "he") said as DEFAULT_SUBJECT. Who moves changes nothing
    in the benchmark's motions, but an unknown subject moves the text's vector: "a figure skater
    pirouettes to the right" stood still in 5 seeds of 5 where "a person pirouettes to the right"
    spun (held-out set 3: 0.533 -> 0.642 of its read-outs for the bundled model). A text without
    a subject, or whose subject is a body part, is unchanged, and so is a trained subject followed
    by the first half of a two-word verb ("a man power walks", "a person side shuffles")."""
    found = _SUBJECT.match(text)
    if found is None:
        return text
    words = found.group(0).lower().split()
    trained = [k for k in range(1, len(words) + 1) if " ".join(words[:k]) in TRAINED_SUBJECTS]
    if _BODY_WORDS & set(words) or (trained and (trained[-1] == len(words)
                                                 or words[trained[-1]] in _VERB_HALVES)):
        return text
    return DEFAULT_SUBJECT + text[found.end():]


def split_actions(text: str) -> list[str]:
    """The parts of a prompt that names actions in sequence; [text] when it names one."""
    parts = [p.strip(" ,;.") for p in _SEQUENCE.split(in_order(text))]
    parts = _returns_joined([p for p in parts if len(p.split()) >= MIN_WORDS])
    parts = [q for p in parts for q in _split_listed(p)]
    if len(parts) < 2:
        return [text]
    found = _SUBJECT.match(parts[0])
    subject = found.group(0) if found else DEFAULT_SUBJECT
    return [parts[0]] + [p if _SUBJECT.match(p) else f"{subject} {_finite_lead(p)}"
                         for p in parts[1:]]


# Going down: a part that names one of these and a "then" part that stands back up are one action
# (the benchmark's sit_stand, squat, kneel and bow all come back up), "pretends to sit on a
# chair, then stands" as "sits down and stands up" is.
_LOWERING = re.compile(r"\b(?:sit|sits|sitting|squat|squats|squatting|kneel|kneels|kneeling|"
                       r"crouch|crouches|crouching|bend|bends|bending|bow|bows|bowing|duck|ducks|"
                       r"ducking|sink|sinks|sinking|hunker|hunkers|hunkering|perch|perches|"
                       r"perching|lower|lowers|lowering|gets?\s+down|getting\s+down)\b",
                       re.IGNORECASE)


# The words of a part that only comes back up ("stands back up", "gets up again", "rises to a
# standing position", "pushes himself back up to his feet"); any other word makes it an action
# of its own: "stands still", "stands quietly", "stands in place" are the benchmark's stand
# family.
_RETURN_WORDS = frozenset({"back", "up", "upright", "again", "straight", "fully", "slowly",
                           "quickly", "to", "a", "standing", "position", "then", "himself",
                           "herself", "themselves", "itself", "his", "her", "their", "its",
                           "feet"})


def _only_returns(phrase: str) -> bool:
    words = re.findall(r"[a-z]+", phrase.lower())
    return (bool(words) and _lemma(words[0]) in _RETURN_VERBS
            and all(w in _RETURN_WORDS for w in words[1:]))


# A part made only of these names no action: "leaning left and then right" is one lean.
_DIRECTION_WORDS = frozenset("left right forward forwards backward backwards back sideways up "
                             "down around round again to the other side way".split())


def _only_directions(phrase: str) -> bool:
    words = re.findall(r"[a-z]+", phrase.lower())
    return bool(words) and all(w in _DIRECTION_WORDS for w in words)


def _returns_joined(parts: list[str]) -> list[str]:
    """Sequence parts with a part that only stands back up (a _RETURN_VERBS verb and
    _RETURN_WORDS) joined to a part before it that goes down: "squats, then stands back up" is
    one squat, "squats, then stands still" two actions. What follows the return after "and" or
    a comma stays a part of its own ("sits, then stands up and walks away": the sit and the
    walk)."""
    out: list[str] = []
    for part in parts:
        if out and _only_directions(part):  # "leans left and then right": one lean
            out[-1] = f"{out[-1]}, then {part}"
            continue
        rest = _without_subject(part)[1]
        head, *tail = _LISTED.split(rest, maxsplit=1)
        if out and _LOWERING.search(out[-1]) and _only_returns(head):
            out[-1] = f"{out[-1]}, then {head}"
            out += [t for t in tail if t.strip()]
            continue
        out.append(part)
    return out


# A verb that completes the action before it rather than starting one ("squats down and stands
# back up", "bends forward and straightens up", "kneels and gets back up"), and the pairs that
# name one action together ("stretches the arms up and leans to the side", "balances on the
# left leg and hops").
_RETURN_VERBS = frozenset({"stand", "straighten", "get", "rise", "push"})
_ONE_ACTION_PAIRS = frozenset({(first, then) for first in ("stretch", "reach", "raise")
                               for then in ("lean", "bend")}
                              | {("raise", "wave"), ("lift", "wave"), ("balance", "hop"),
                                 ("bend", "drop"), ("crouch", "drop")})
_LISTED = re.compile(r"\s*,\s*(?:and\s+)?|\s+and\s+", re.IGNORECASE)


def _split_listed(phrase: str) -> list[str]:
    """A phrase listing actions with commas or "and" ("claps twice and jabs with the right arm",
    "punches twice, jogs ahead"), one piece per action: a piece that starts with a verb we know
    starts a new action unless it completes the one before (_RETURN_VERBS, _ONE_ACTION_PAIRS).
    "turns three hundred and sixty degrees" and "walks forward and back" stay whole. The pieces
    after the first have no subject: split_actions gives them one (and makes a gerund finite)."""
    if _WHILE.search(phrase) or _SAME_TIME.search(phrase.strip(" ,;.")):
        return [phrase]  # actions at once, not one after another
    subject, rest = _without_subject(phrase)
    pieces = _LISTED.split(rest)
    separators = [m.group(0) for m in _LISTED.finditer(rest)]
    current = _leading_verb(pieces[0])
    if current is None:
        return [phrase]
    finite = _leading_word(pieces[0]) in _THIRD_PERSON
    actions = [pieces[0]]
    for separator, piece in zip(separators, pieces[1:]):
        verb = _leading_verb(piece)
        # a part that opens with standing ("stands and claps", "stands on the left leg and
        # hops") is the action that follows it
        opens_standing = len(actions) == 1 and current in _RETURN_VERBS
        # after a finite verb, a comma and a gerund say how ("sidesteps along the line, going
        # to his right"); in a progressive list ("is walking, turning left and ...") the
        # gerunds are the actions
        manner = finite and "," in separator and _leading_word(piece) in _GERUND
        if (verb is None or verb in _RETURN_VERBS or (current, verb) in _ONE_ACTION_PAIRS
                or opens_standing or manner):
            current = verb if opens_standing and verb is not None else current
            actions[-1] += separator + piece
            continue
        actions.append(piece)
        current = verb
    if len(actions) == 1:
        return [phrase]
    return [f"{subject} {actions[0]}" if subject else actions[0], *actions[1:]]


# words before a verb that leave the piece's action as it is ("first hops", "is spinning")
_ADVERBS = frozenset({"first", "finally", "also", "then", "again", "is", "are"})


def _leading_word(piece: str) -> str:
    """The word a piece starts with, past two adverbs ("is slowly walking": "walking")."""
    words = piece.lower().split()
    for _ in range(2):  # "is slowly walking"
        if len(words) > 1 and (words[0].endswith("ly") or words[0] in _ADVERBS):
            words = words[1:]
    return words[0] if words else ""


def _leading_verb(piece: str) -> str | None:
    """The lemma of the verb a piece starts with, past two adverbs ("is slowly walking"); None when
    it starts otherwise ("back", "sixty degrees")."""
    word = _leading_word(piece)
    if not word or word == "back":  # "walks forward and back": a direction here
        return None
    return _lemma(word)


def _finite_lead(phrase: str) -> str:
    """"jogging forward" -> "jogs forward": a leading gerund made finite, the rest unchanged."""
    head, _, tail = phrase.partition(" ")
    lemma = _GERUND.get(head.lower())
    return f"{VERB_FORMS[lemma][0]} {tail}".strip() if lemma else phrase


# Verbs of an arm action (lemmas): a "while" clause led by one of them is made on the arms alone.
ARM_VERBS = frozenset({"wave", "clap", "punch", "jab", "throw", "box", "raise", "lift", "put"})
_THIRD_PERSON = {forms[0]: lemma for lemma, forms in VERB_FORMS.items()}
_GERUND = {forms[1]: lemma for lemma, forms in VERB_FORMS.items()}
_WHILE = re.compile(r"\s*,?\s*\bwhile\b\s*", re.IGNORECASE)
_SAME_TIME = re.compile(r"\s*,?\s*\b(?:at\s+the\s+same\s+time|simultaneously)\s*$",
                        re.IGNORECASE)
_AND = re.compile(r"\s+and\s+", re.IGNORECASE)
_GERUND_WORD = re.compile(r"\b[a-z]+ing\b", re.IGNORECASE)  # anywhere in a phrase (_finite)


def _lemma(word: str) -> str | None:
    word = word.lower()
    return _THIRD_PERSON.get(word) or _GERUND.get(word) or (word if word in VERB_FORMS else None)


def _without_subject(phrase: str) -> tuple[str, str]:
    """(subject or "", the rest) of a phrase."""
    found = _SUBJECT.match(phrase)
    if not found:
        return "", phrase
    return found.group(0), phrase[found.end():].strip()


def _first_verb(phrase: str) -> str | None:
    return _leading_verb(_without_subject(phrase)[1])


def _is_arm_action(phrase: str) -> bool:
    return _first_verb(phrase) in ARM_VERBS


def _finite(phrase: str) -> str:
    """A gerund phrase made finite: "waving his hand and clapping" -> "waves his hand and claps"."""
    def verb(match: re.Match[str]) -> str:
        lemma = _GERUND.get(match.group(0).lower())
        return VERB_FORMS[lemma][0] if lemma else match.group(0)
    return _GERUND_WORD.sub(verb, phrase)


def _split_phrase(phrase: str) -> tuple[str, str] | None:
    """(the body's phrase, the arms' phrase) of one phrase naming two actions at once, or None."""
    pairs = []
    phrase = phrase.strip(" ,;.")
    if _WHILE.search(phrase):
        first, second = _WHILE.split(phrase, maxsplit=1)
        pairs.append((first, _finite(second)))
    elif _SAME_TIME.search(phrase):
        both = _SAME_TIME.sub("", phrase)
        pairs += [(both[:m.start()], _finite_lead(both[m.end():])) for m in _AND.finditer(both)]
    for first, second in pairs:
        first, second = first.strip(" ,;."), second.strip(" ,;.")
        if not first or not second:
            continue
        # both sides must start with a verb we know: "waves while smiling" is one action
        if _first_verb(first) is None or _first_verb(second) is None:
            continue
        if _is_arm_action(second) and not _is_arm_action(first):
            return first, second
        if _is_arm_action(first) and not _is_arm_action(second):
            subject = _without_subject(first)[0]
            return (f"{subject} {second}" if subject else second), first
    return None


def split_concurrent(text: str) -> tuple[str, str] | None:
    """(the body's prompt, the arms' prompt) of a prompt that names an arm action done at the
    same time as another action, or None. The body's prompt is the text without the arm action
    (it may still be a sequence); the arms' prompt gets the text's subject."""
    pieces = re.split(f"({_SEQUENCE.pattern})", text, flags=re.IGNORECASE)
    for k in range(0, len(pieces), 2):  # the phrases; odd indices are the separators
        split = _split_phrase(pieces[k])
        if split is None:
            continue
        body, arms = split
        found = _SUBJECT.match(text.strip())
        subject = found.group(0) if found else DEFAULT_SUBJECT
        if not _SUBJECT.match(arms):
            arms = f"{subject} {arms}"
        if k > 0 and body.startswith(subject):  # a later phrase keeps the sequence's wording
            body = body[len(subject):].strip()
        return "".join(pieces[:k] + [body] + pieces[k + 1:]).strip(), arms
    return None


_CLAUSE_FIRST = re.compile(r"^\s*(after|before)\s+((?:[a-z]+ly\s+)?[a-z]+ing\b[^,]*),\s*(.+)$",
                           re.IGNORECASE)
_CLAUSE_LAST = re.compile(r"^(.+?)\s*,?\s+\b(after|before)\s+((?:[a-z]+ly\s+)?[a-z]+ing\b.*)$",
                          re.IGNORECASE)


def in_order(text: str) -> str:
    """A prompt whose "after"/"before" + gerund clause names an action, rewritten with "then" in
    the order the actions happen; other prompts unchanged. "after walking forward, a man turns
    left" and "a man turns left after walking forward" -> "a man walks forward, then turns left";
    "before turning, a man walks" and "a man walks before turning" -> "a man walks, then turns"."""
    found = _CLAUSE_FIRST.match(text)
    if found:
        word, clause, main = found.groups()
    else:
        found = _CLAUSE_LAST.match(text)
        if not found:
            return text
        main, word, clause = found.groups()
    if _leading_verb(clause.strip(" ,;.")) is None:  # "before the door": no action
        return text
    clause, main = _finite(clause.strip(" ,;.")), main.strip(" ,;.")
    subject, rest = _without_subject(main)
    subject = subject or DEFAULT_SUBJECT
    first, then = (clause, rest or main) if word.lower() == "after" else (rest or main, clause)
    return f"{subject} {first}, then {then}"


def portable_rules() -> dict:
    """split_actions' and split_concurrent's word lists and patterns as JSON, for the static
    site's port of them (serve/site/static/compose.js): the rules stay here, written once, and
    the page reads them from model.json. Every pattern is case-insensitive (JavaScript flags
    "iu": Unicode case folding, as Python's)."""
    patterns = {"sequence": _SEQUENCE, "subject": _SUBJECT, "lowering": _LOWERING,
                "listed": _LISTED, "while": _WHILE, "same_time": _SAME_TIME,
                "clause_first": _CLAUSE_FIRST, "clause_last": _CLAUSE_LAST,
                "gerund_word": _GERUND_WORD, "and": _AND}
    assert all(p.flags & re.IGNORECASE for p in patterns.values())
    return {"patterns": {name: p.pattern for name, p in patterns.items()},
            "verb_forms": {lemma: list(forms) for lemma, forms in VERB_FORMS.items()},
            "return_verbs": sorted(_RETURN_VERBS), "return_words": sorted(_RETURN_WORDS),
            "one_action_pairs": sorted([a, b] for a, b in _ONE_ACTION_PAIRS),
            "adverbs": sorted(_ADVERBS), "arm_verbs": sorted(ARM_VERBS),
            "default_subject": DEFAULT_SUBJECT, "trained_subjects": sorted(TRAINED_SUBJECTS),
            "body_words": sorted(_BODY_WORDS), "verb_halves": sorted(_VERB_HALVES),
            "direction_words": sorted(_DIRECTION_WORDS), "min_words": MIN_WORDS}
