"""Prompts from people: checked once, here, for the CLI, the Python API and the server alike.

A prompt is one line of printable text. Runs of whitespace become one space; control characters
(other than whitespace), an empty prompt or one longer than MAX_PROMPT_CHARS are errors that name
the problem, so nothing reaches the text encoder that it would silently truncate or mangle.
"""

from __future__ import annotations

import os
import re
import unicodedata
from pathlib import Path

from mlct.errors import MlctError

# MiniLM and CLIP read at most 256 and 77 tokens; 500 characters is past both, and past any
# caption of HumanML3D (the longest is about 300), so a longer text is a mistake, not a prompt.
MAX_PROMPT_CHARS = 500


def clean_prompt(text: object, where: str = "") -> str:
    """text with whitespace runs collapsed; MlctError when it is empty, too long or has controls."""
    at = f" ({where})" if where else ""
    if not isinstance(text, str):
        raise MlctError(f"a prompt must be a string, not {type(text).__name__}{at}")
    for char in text:
        if unicodedata.category(char) in ("Cc", "Cf", "Cs") and not char.isspace():
            raise MlctError(f"the prompt contains the control character U+{ord(char):04X}{at}")
    cleaned = " ".join(text.split())
    if not cleaned:
        raise MlctError(f"the prompt is empty{at}; describe a motion, "
                        f"e.g. 'a person walks forward'")
    if len(cleaned) > MAX_PROMPT_CHARS:
        raise MlctError(f"the prompt has {len(cleaned)} characters{at}; the limit is "
                        f"{MAX_PROMPT_CHARS}")
    return cleaned


def read_prompts(path: str | os.PathLike) -> list[str]:
    """The prompts of a UTF-8 file, one a line; blank lines and lines starting with # are skipped."""
    path = Path(path)
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise MlctError(f"{path}: line {line} is not valid UTF-8") from None
    prompts = []
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.lstrip().startswith("#"):
            prompts.append(clean_prompt(line, f"{path.name} line {number}"))
    if not prompts:
        raise MlctError(f"{path}: no prompts (one a line)")
    return prompts


# "... for 20 seconds", "..., for about half a minute": how long the person does it. The model
# never saw a duration in a caption, so the phrase is taken out of the text it reads and, unless
# the caller gave the length, sets the clip's.
_NUMBERS = {"a": 1, "an": 1, "one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6,
            "seven": 7, "eight": 8, "nine": 9, "ten": 10, "eleven": 11, "twelve": 12,
            "fifteen": 15, "twenty": 20, "thirty": 30, "forty": 40, "forty-five": 45,
            "fifty": 50, "sixty": 60, "ninety": 90, "half a": 0.5}
_UNITS = {"second": 1.0, "sec": 1.0, "s": 1.0, "minute": 60.0, "min": 60.0}
# Digits are ASCII ([0-9], not \d, which also takes other scripts' digits): as the page reads
# them (static/compose.js: StatedSeconds, from portable_stated).
_STATED = re.compile(
    r"\s*[,;]?\s*\bfor\s+(?:about\s+|around\s+|roughly\s+)?"
    r"(?P<n>[0-9]+(?:\.[0-9]+)?|" + "|".join(sorted((re.escape(k) for k in _NUMBERS), key=len,
                                             reverse=True)) + r")"
    r"\s*(?P<unit>seconds?|secs?|s|minutes?|mins?)\b", re.IGNORECASE)


def stated_seconds(text: str) -> tuple[str, float | None]:
    """(the text without its duration phrase, the seconds it states): ("a person walks forward",
    20.0) for "a person walks forward for 20 seconds"; (text, None) when it states none, or more
    than one ("walks for 5 seconds, then waves for 3 seconds": whose is whose is the parts')."""
    found = list(_STATED.finditer(text))
    if len(found) != 1:
        return text, None
    match = found[0]
    number = match.group("n").lower()
    amount = float(number) if number[0].isdigit() else float(_NUMBERS[number])
    unit = match.group("unit").lower().rstrip("s") or "s"
    seconds = amount * _UNITS[unit]
    rest = (text[:match.start()] + text[match.end():]).strip(" ,;")
    if seconds <= 0 or not rest:
        return text, None
    return " ".join(rest.split()), seconds


def portable_stated() -> dict:
    """stated_seconds' pattern, number words and units as JSON, for the static site's port
    (serve/site/static/compose.js: StatedSeconds); the pattern is case-insensitive."""
    assert _STATED.flags & re.IGNORECASE
    return {"pattern": _STATED.pattern, "numbers": _NUMBERS, "units": _UNITS}
