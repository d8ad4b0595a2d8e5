"""How generate() reads a prompt: the parts it makes (its actions in turn, an arm action done
during them), each as the text encoder gets it, how far the text anchors pull it, and whether
the model knows it (unknown_prompts.py); `mlct generate --verbose` prints it."""

from __future__ import annotations

import logging
from typing import Any, Sequence

from mlct.errors import MlctError
from mlct.generate.compose.actions import plain_subject, split_actions, split_concurrent
from mlct.generate.compose.lengths import stated_lengths
from mlct.generate.compose.prompts import clean_prompt

# What the pipeline decided beyond the model's own sampling; `mlct generate --verbose` prints it.
LOG = logging.getLogger("mlct.generate")


def parts_as_made(text: str, split: bool) -> tuple[list[str], str | None]:
    """(the actions made in turn, the arm action made during them or None): how generate()
    splits a prompt, an arm action done during the rest first (actions.split_concurrent), then
    the rest's actions (actions.split_actions); (text,), None when not split."""
    pair = split_concurrent(text) if split else None
    body, arms = (text, None) if pair is None else pair
    return (split_actions(body) if split else [body]), arms


def unknown_parts(gen: Any, texts: str | Sequence[str], split_actions: bool = True
                  ) -> list[tuple[str, ...]]:
    """For each prompt, the parts of it (as generate() splits it: its actions in turn, an
    arm action done during them) that lie too far from every training caption for the
    model to know them (unknown_prompts.py); () where it knows them all, or where the model
    has no text anchors to judge by. Reads the text encoder's memo without changing it, so
    that judging a prompt never changes a later motion."""
    from mlct.generate.compose.unknown_prompts import unknown_rows

    texts = [texts] if isinstance(texts, str) else list(texts)
    clean, _ = stated_lengths([clean_prompt(t) for t in texts], split_actions)
    plans = [parts_as_made(t, split_actions) for t in clean]
    parts = [[*body, *([arms] if arms else [])] for body, arms in plans]
    distinct = list(dict.fromkeys(p for plan in parts for p in plan))
    if gen.known_anchors is None or not distinct:
        return [() for _ in texts]
    unknown = dict(zip(distinct, unknown_rows(gen.known_anchors,
                                              gen.core.judged_vectors(distinct))))
    return [tuple(p for p in plan if unknown[p]) for plan in parts]


def reading(gen: Any, text: str, split_actions: bool = True) -> list[dict[str, Any]]:
    """How generate() reads a prompt, one dict per sample it makes: "part" (the words, as
    split from the prompt), "read_as" (as the text encoder gets them: actions.plain_subject),
    "pull" (how far the text anchors move its vector, 0 to 1), "arms" (True for an arm
    action done during the rest) and "known" (False: too far from every training caption
    for the model to know it, unknown_prompts.py). A misreading shows here first
    ("a little girl in a party dress twirls" was once read as "a person dress twirls")."""
    body, arms = parts_as_made(clean_prompt(text), split_actions)
    parts = body + ([arms] if arms else [])
    vectors = gen.encode_text(parts)
    pulls = (gen.text_anchors.weights(vectors)[0].tolist()
             if gen.text_anchors is not None else [0.0] * len(parts))
    if gen.known_anchors is not None:
        from mlct.generate.compose.unknown_prompts import unknown_rows

        known = [not u for u in unknown_rows(gen.known_anchors, vectors)]
    else:
        known = [True] * len(parts)
    return [{"part": part, "read_as": plain_subject(part), "pull": round(pull, 3),
             "arms": k == len(body), "known": ok}
            for k, (part, pull, ok) in enumerate(zip(parts, pulls, known))]


def log_reading(gen: Any, texts: Any, split: bool) -> None:
    """--verbose: each prompt's reading() as one line."""
    if not isinstance(texts, (list, tuple)):
        texts = [texts]
    for text in texts:
        try:
            parts = reading(gen, text, split)
        except MlctError:
            continue  # generate() refuses it with its own message
        said = [f"{p['read_as']!r}" + (f" (pulled {p['pull']:.2f} towards the training "
                                         f"captions)" if p["pull"] else "")
                + ("" if p["known"] else " (unknown to the model)")
                for p in parts]
        body = [w for w, p in zip(said, parts) if not p["arms"]]
        arms = [w for w, p in zip(said, parts) if p["arms"]]
        LOG.info("%r read as %s%s", text, ", then ".join(body),
                 f"; its arms as {arms[0]}" if arms else "")
