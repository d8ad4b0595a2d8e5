"""Whole-body families of benchmark version 4: crawling, stairs, falls, carrying and pushing,
uneven and balancing walks, jumps.

Every family module of version 4 (this one, families_arms.py) has the same interface, which
actions.py, more_clips.py, the four vocabularies (text.py, everyday.py, colloquial.py, short.py)
and the caption lexicon (mlct.data.captions) merge; the module imports none of them, so that
each of those can take its entries from here:

- PARAMS: family -> {parameter: its possible values} (actions.FAMILY_PARAMS);
- CLIPS: family -> clip function (rig, fps, style, **params) -> motions.Clip, as more_clips';
- PHRASES: vocabulary ("benchmark", "everyday", "colloquial", "short") -> family -> phrase
  (params, rng) -> str, with the <verb> marks and HIS of text.py and each vocabulary's rules
  (phrases_more.py);
- VERBS: vocabulary ("benchmark", "everyday", "colloquial") -> lemma -> (third person,
  gerund) of the verbs its phrases mark that the vocabulary lacks (the short vocabulary uses
  the benchmark's);
- WORDS: word -> part of speech (NOUN, ADJ, ADV, ADP, ...) and PLURALS: plural -> singular,
  the other words of its benchmark captions that the lexicon lacks;
- ENDS_DOWN / STARTS_DOWN: families that end on the floor (nothing follows them in a script)
  and that start lying on the back (first in a script, or right after lying down).
"""

from __future__ import annotations

from typing import Callable

from mlct.data.synth.motions import Clip
from mlct.data.synth.phrases_more import Phrase

PARAMS: dict[str, dict[str, tuple]] = {}
CLIPS: dict[str, Callable[..., Clip]] = {}
PHRASES: dict[str, dict[str, Phrase]] = {"benchmark": {}, "everyday": {}, "colloquial": {},
                                         "short": {}}
VERBS: dict[str, dict[str, tuple[str, str]]] = {"benchmark": {}, "everyday": {},
                                                "colloquial": {}}
WORDS: dict[str, str] = {}
PLURALS: dict[str, str] = {}
ENDS_DOWN: frozenset[str] = frozenset()
STARTS_DOWN: frozenset[str] = frozenset()
