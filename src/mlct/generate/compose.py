"""Prompts that name actions one after another: split into one prompt per action.

"a person walks forward, then waves with the right hand" is two motions in a row. The model
draws one action per prompt far better than a sequence in one latent (docs/model_card.md: the
two-action prompts pass 0.00 of their checks as one prompt), and the long-motion chaining
(long_motion.py) already joins prompts into one continuous motion. So the pipeline splits such a
prompt at its sequencing words and chains the parts, each with an equal share of the length.

Only words that put the next action after the previous one split: "then", "and then", "after
that", "afterwards". These do not: "while" (two actions at once), "and" alone (often one action:
"turns around and walks back"), "next" (mostly an adjective: "the next room"), "followed by" (a
noun follows: "followed by a bow"). "after"/"before" with a gerund clause are put in the order
of the actions first (in_order: "turns left after walking forward" is "walks forward, then turns
left"). A part without its own subject gets the first part's ("a person" when none is found),
so every part reads like a caption.

Actions at the same time ("walks forward while waving the right hand", "... and claps at the
same time") are split too when one of the two is an arm action (split_concurrent): the
autoencoder's three latent tokens hold a gait or an arm action, not both (the "+ concurrent"
row of bench/motion_quality.py: 0.02 of such motions survive reconstruction), so the body is
made from the rest of the prompt and the arms from the arm action alone, grafted on
(generate/control_fit.py's reattach, a body-part edit).
"""

from __future__ import annotations

import re

from mlct.data.captions import VERB_FORMS

# The sequencing words, with the punctuation and "and" that may come with them.
_SEQUENCE = re.compile(
    r"\s*(?:[,;.]\s*)?(?:\band\s+)?\b(?:then|after\s+that|afterwards)\b"
    r"\s*,?\s*", re.IGNORECASE)
_SUBJECT = re.compile(
    r"^(?:(?:a|an|the|this|that)\s+[a-z]+|someone|somebody|he|she|they|it|person|man|woman|"
    r"human|figure)\b", re.IGNORECASE)
DEFAULT_SUBJECT = "a person"
MIN_WORDS = 1  # a part must name something to be a prompt of its own


def split_actions(text: str) -> list[str]:
    """The parts of a prompt that names actions in sequence; [text] when it names one."""
    parts = [p.strip(" ,;.") for p in _SEQUENCE.split(in_order(text))]
    parts = [p for p in parts if len(p.split()) >= MIN_WORDS]
    if len(parts) < 2:
        return [text]
    found = _SUBJECT.match(parts[0])
    subject = found.group(0) if found else DEFAULT_SUBJECT
    return [parts[0]] + [p if _SUBJECT.match(p) else f"{subject} {p}" for p in parts[1:]]


# Verbs of an arm action (lemmas): a "while" clause led by one of them is made on the arms alone.
ARM_VERBS = frozenset({"wave", "clap", "punch", "jab", "throw", "box", "raise", "lift", "put"})
_THIRD_PERSON = {forms[0]: lemma for lemma, forms in VERB_FORMS.items()}
_GERUND = {forms[1]: lemma for lemma, forms in VERB_FORMS.items()}
_WHILE = re.compile(r"\s*,?\s*\bwhile\b\s*", re.IGNORECASE)
_SAME_TIME = re.compile(r"\s*,?\s*\b(?:at\s+the\s+same\s+time|simultaneously)\s*$",
                        re.IGNORECASE)
_AND = re.compile(r"\s+and\s+", re.IGNORECASE)


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
    words = _without_subject(phrase)[1].split()
    return _lemma(words[0]) if words else None


def _is_arm_action(phrase: str) -> bool:
    return _first_verb(phrase) in ARM_VERBS


def _finite(phrase: str) -> str:
    """A gerund phrase made finite: "waving his hand and clapping" -> "waves his hand and claps"."""
    def verb(match: re.Match[str]) -> str:
        lemma = _GERUND.get(match.group(0).lower())
        return VERB_FORMS[lemma][0] if lemma else match.group(0)
    return re.sub(r"\b[a-z]+ing\b", verb, phrase, flags=re.IGNORECASE)


def _split_phrase(phrase: str) -> tuple[str, str] | None:
    """(the body's phrase, the arms' phrase) of one phrase naming two actions at once, or None."""
    pairs = []
    if _WHILE.search(phrase):
        first, second = _WHILE.split(phrase, maxsplit=1)
        pairs.append((first, _finite(second)))
    elif _SAME_TIME.search(phrase):
        both = _SAME_TIME.sub("", phrase)
        pairs += [(both[:m.start()], both[m.end():]) for m in _AND.finditer(both)]
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


_CLAUSE_FIRST = re.compile(r"^\s*(after|before)\s+([a-z]+ing\b[^,]*),\s*(.+)$", re.IGNORECASE)
_CLAUSE_LAST = re.compile(r"^(.+?)\s*,?\s+\b(after|before)\s+([a-z]+ing\b.*)$", re.IGNORECASE)


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
    if _GERUND.get(clause.split()[0].lower()) is None:  # "before the door": no action
        return text
    clause, main = _finite(clause.strip(" ,;.")), main.strip(" ,;.")
    subject, rest = _without_subject(main)
    subject = subject or DEFAULT_SUBJECT
    first, then = (clause, rest or main) if word.lower() == "after" else (rest or main, clause)
    return f"{subject} {first}, then {then}"
