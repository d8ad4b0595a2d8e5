"""Prompts that name actions one after another: split into one prompt per action.

"a person walks forward, then waves with the right hand" is two motions in a row. The model
draws one action per prompt far better than a sequence in one latent (docs/model_card.md: the
two-action prompts pass 0.00 of their checks as one prompt), and the long-motion chaining
(long_motion.py) already joins prompts into one continuous motion. So the pipeline splits such a
prompt at its sequencing words and chains the parts, each with an equal share of the length.

Only words that put the next action after the previous one split: "then", "and then", "after
that", "afterwards". These do not: "while" (two actions at once), "and" alone (often one action:
"turns around and walks back"), "next" (mostly an adjective: "the next room"), "followed by" (a
noun follows: "followed by a bow") and "after"/"before" with a clause (whose order would need
parsing). A part without its own subject gets the first part's ("a person" when none is found),
so every part reads like a caption.
"""

from __future__ import annotations

import re

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
    parts = [p.strip(" ,;.") for p in _SEQUENCE.split(text)]
    parts = [p for p in parts if len(p.split()) >= MIN_WORDS]
    if len(parts) < 2:
        return [text]
    found = _SUBJECT.match(parts[0])
    subject = found.group(0) if found else DEFAULT_SUBJECT
    return [parts[0]] + [p if _SUBJECT.match(p) else f"{subject} {p}" for p in parts[1:]]
