"""Prompts from people: checked once, here, for the CLI, the Python API and the server alike.

A prompt is one line of printable text. Runs of whitespace become one space; control characters
(other than whitespace), an empty prompt or one longer than MAX_PROMPT_CHARS are errors that name
the problem, so nothing reaches the text encoder that it would silently truncate or mangle.
"""

from __future__ import annotations

import os
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
