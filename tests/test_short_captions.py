"""The short caption vocabulary (data/synth/short.py): each action by its bare verb, truthful
(a side, count or angle left out, never a wrong one; a bare turn is a quarter turn and a bare
jump is in place, as the benchmark's captions mean them), in the benchmark's verbs only, and
`mlct data rephrase --vocabulary short` on top of an already rephrased copy."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mlct.data.captions import VERB_FORMS
from mlct.data.labels import read_labels
from mlct.data.layout import DatasetLayout
from mlct.data.synth.rephrase import rephrase_dataset
from mlct.data.synth.short import SHORT
from mlct.data.synth.text import FAMILIES, describe
from mlct.errors import MlctError
from test_everyday import make_benchmark
from test_synth_text import act, param_grid, random_motion

BENCHMARK_WORDS = {w for forms in VERB_FORMS.values() for w in forms} | set(VERB_FORMS)


def short(actions: list, seeds: int = 8, **kw: object) -> list[str]:
    return [c for s in range(seeds)
            for c in describe(actions, np.random.default_rng(s), vocabulary=SHORT, **kw)]


SIDE_KEYS = ("side", "hand", "leg")
DIRECTIONS = ("turn", "spin", "circle", "side_step")


@pytest.mark.parametrize("family", FAMILIES)
def test_short_captions_name_no_wrong_side_or_count(family: str) -> None:
    for params in param_grid(family):
        caps = short([act(family, **params)])
        said = " | ".join(caps)
        assert all(not re.search(r"[<>]|\bHIS\b|\s,|\s\s", c) for c in caps), said
        side = next((params[k] for k in SIDE_KEYS if k in params), None)
        if side == "left" and family not in DIRECTIONS:
            # the left side in the benchmark's words, which name it (counts may be said)
            assert all(re.search(r"\bleft\b", c) for c in caps), said
            assert not re.search(r"\bright\b", said), said
            continue
        if family == "turn" and params["angle"] != 90:
            # only a quarter turn goes without its size; the others keep the benchmark's words
            assert not any(re.fullmatch(rf"[a-z ]+ (turns|is turning) (to the )?{side}\.", c)
                           for c in caps), said
            continue
        if family == "jump" and params["mode"] == "forward":
            # a bare "jumps" is in place; a forward jump says so
            assert all(re.search(r"\b(forward|ahead)\b", c) for c in caps), said
            continue
        if family == "jump":  # in place: the count may be said, and only the right one
            wrong = {1: r"twice|two|three|[23]", 2: r"once|three|[13]", 3: r"once|twice|two|[12]"}
            assert not re.search(rf"\b({wrong[params['count']]})\b", said), said
            assert not re.search(r"\b(forward|ahead)\b", said), said
            continue
        assert not re.search(r"\b(twice|three|four|five|degrees|once|\d)\b", said), said
        if family in DIRECTIONS:  # a direction is said, the right one
            other = "right" if side == "left" else "left"
            assert all(re.search(rf"\b{side}\b", c) for c in caps), said
            assert not re.search(rf"\b{other}\b", said), said
        else:  # "a person kicks" means the right leg: no side said
            assert not re.search(r"\b(left|right)\b", said), said
            assert all(len(c.split()) <= 9 for c in caps), said
        if side == "both":
            assert all(re.search(r"\bboth\b|\bhis\b|\bher\b|\btheir\b|\bthe\b", c)
                       for c in caps), said
            assert not re.search(r"\b(a|one) (hand|arm)\b", said), said


@pytest.mark.parametrize("family", ["wave", "stretch", "walk", "kick", "clap", "bow"])
def test_the_bare_verb_is_said(family: str) -> None:
    verb = {"wave": "waves", "stretch": "stretches", "walk": "walks", "kick": "kicks",
            "clap": "claps", "bow": "bows"}[family]
    params = next(p for p in param_grid(family) if "left" not in p.values()
                  and "both" not in p.values())
    caps = short([act(family, **params)], seeds=20)
    assert any(re.fullmatch(rf"[a-z ]+ {verb}\.", c) for c in caps), caps


def test_short_captions_use_only_the_benchmarks_verbs_and_chain_in_order() -> None:
    rng = np.random.default_rng(0)
    for _ in range(300):
        actions, concurrent = random_motion(rng)
        for caption in describe(actions, rng, concurrent=concurrent, vocabulary=SHORT):
            words = re.findall(r"[a-z]+", caption)
            verbs = [w for w in words if w in BENCHMARK_WORDS]
            assert verbs, caption
    caps = short([act("walk", speed="normal", direction="forward"), act("wave", hand="left",
                                                                        count=2)])
    assert any(re.search(r"walks.*(then|and).*wav", c) for c in caps), caps


def test_rephrase_short_on_a_rephrased_copy_records_both_steps(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    rephrase_dataset(src, tmp_path / "rich", per_motion=1)
    summary = rephrase_dataset(tmp_path / "rich", tmp_path / "short", per_motion=2,
                               vocabulary="short")
    rich, out = DatasetLayout.existing(tmp_path / "rich"), DatasetLayout.existing(tmp_path / "short")
    train = rich.read_split("train")
    labels = read_labels(tmp_path / "short")
    assert summary == {"motions": len(train), "captions": 2 * len(train)}
    for name in train:
        old = [t.caption for t in rich.read_texts(name)]
        new = [t.caption for t in out.read_texts(name)]
        assert new[: len(old)] == old and len(new) == len(old) + 2
        # degrees are said only where the benchmark's words name a turn other than a quarter one
        other_turn = any(a["family"] == "turn" and a["params"]["angle"] != 90
                         for a in labels[name]["actions"])
        assert other_turn or not any(re.search(r"\bdegrees\b", c) for c in new[len(old):]), new
    steps = json.loads((tmp_path / "short" / "synth.json").read_text())["rephrased"]
    assert [s["vocabulary"] for s in steps] == ["everyday", "short"]
    with pytest.raises(MlctError, match="vocabulary must be one of"):
        rephrase_dataset(src, tmp_path / "other", vocabulary="poetic")
    assert not (tmp_path / "other").exists()


def test_cli_rephrase_short(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    run = [sys.executable, "-m", "mlct.cli", "data", "rephrase", str(src), "--out"]
    ok = subprocess.run(run + [str(tmp_path / "s"), "--vocabulary", "short"], capture_output=True,
                        text=True)
    assert ok.returncode == 0 and "short captions added" in ok.stdout, ok.stderr
    bad = subprocess.run(run + [str(tmp_path / "t"), "--vocabulary", "poetic"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "vocabulary" in bad.stderr and "Traceback" not in bad.stderr
