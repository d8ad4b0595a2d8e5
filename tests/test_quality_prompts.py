"""The hand-written prompt sets of bench/quality.py (bench/data): labels the read-outs can judge."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from mlct.data.synth.actions import FAMILIES_BY_VERSION
from mlct.eval.readouts import checks_for

# The prompt sets judge the bundled model, trained on benchmark version 2: its 21 families.
FAMILIES = FAMILIES_BY_VERSION[2]

DATA = Path(__file__).parents[1] / "bench" / "data"


def test_the_second_held_out_set_covers_every_family_with_judgeable_labels() -> None:
    prompts = json.loads((DATA / "quality_prompts_heldout2.json").read_text())["paraphrases"]
    families = Counter(p["actions"][0]["family"] for p in prompts)
    assert families == {f: 3 if f == "turn" else 2 for f in FAMILIES}
    earlier = {p["text"] for name in ("quality_prompts.json", "quality_prompts_heldout.json")
               for p in json.loads((DATA / name).read_text())["paraphrases"]}
    assert len({p["text"] for p in prompts}) == len(prompts) and not earlier & {
        p["text"] for p in prompts}
    for prompt in prompts:
        assert len(prompt["actions"]) == 1 and checks_for(prompt["actions"][0])


def test_the_three_action_prompts_split_into_their_actions_with_judgeable_labels() -> None:
    from mlct.generate.compose.actions import split_actions

    prompts = json.loads((DATA / "quality_prompts_three_actions.json").read_text())
    prompts = prompts["three_actions"]
    assert len(prompts) >= 15 and len({p["text"] for p in prompts}) == len(prompts)
    for prompt in prompts:
        assert len(prompt["actions"]) == 3 and all(checks_for(a) for a in prompt["actions"])
        assert len(split_actions(prompt["text"])) == 3, prompt["text"]


SETS_IN_ORDER = ("quality_prompts.json", "quality_prompts_heldout.json",
                 "quality_prompts_heldout2.json", "quality_prompts_heldout3.json",
                 "quality_prompts_heldout4.json", "quality_prompts_heldout5.json",
                 "quality_prompts_heldout6.json", "quality_prompts_heldout7.json")


@pytest.mark.parametrize("name, fewest", [("quality_prompts_heldout3.json", 45),
                                          ("quality_prompts_heldout4.json", 42),
                                          ("quality_prompts_heldout5.json", 42),
                                          ("quality_prompts_heldout6.json", 42),
                                          ("quality_prompts_heldout7.json", 42)])
def test_a_late_held_out_set_covers_every_family_with_judgeable_labels(name: str,
                                                                      fewest: int) -> None:
    """Held-out sets 3 to 7: two prompts or more per family, none repeating a set before it,
    each one action the read-outs can judge."""
    prompts = json.loads((DATA / name).read_text())["paraphrases"]
    families = Counter(p["actions"][0]["family"] for p in prompts)
    assert set(families) == set(FAMILIES) and min(families.values()) >= 2
    earlier = {p["text"] for before in SETS_IN_ORDER[:SETS_IN_ORDER.index(name)]
               for p in json.loads((DATA / before).read_text())["paraphrases"]}
    assert len({p["text"] for p in prompts}) == len(prompts) >= fewest
    assert not earlier & {p["text"] for p in prompts}
    for prompt in prompts:
        assert len(prompt["actions"]) == 1 and checks_for(prompt["actions"][0])
