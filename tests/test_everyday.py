"""The everyday caption vocabulary and `mlct data rephrase`: truthful captions in other words, a
copy of the benchmark whose training split says each motion in more ways, and a held-out
paraphrase set that shares none of the vocabulary's new verbs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mlct.data.captions import VERB_FORMS, parse_text_line
from mlct.data.layout import DatasetLayout
from mlct.data.synth.everyday import EVERYDAY, EVERYDAY_VERBS, FORMS
from mlct.data.synth.rephrase import rephrase_dataset
from mlct.data.synth.text import FAMILIES, describe
from mlct.errors import MlctError
from test_synth_text import act, counts_said, param_grid, random_motion

HELDOUT = Path(__file__).parents[1] / "bench" / "data" / "quality_prompts_heldout.json"
BENCHMARK_WORDS = {w for forms in VERB_FORMS.values() for w in forms} | set(VERB_FORMS)


def captions_in(vocabulary, actions: list, seeds: int = 12, **kw: object) -> list[str]:
    """A vocabulary's captions of `actions`, over `seeds` seeds."""
    return [c for s in range(seeds)
            for c in describe(actions, np.random.default_rng(s), vocabulary=vocabulary, **kw)]


def everyday(actions: list, seeds: int = 12, **kw: object) -> list[str]:
    return captions_in(EVERYDAY, actions, seeds, **kw)


@pytest.mark.parametrize("family", FAMILIES)
def test_everyday_captions_state_no_wrong_side_count_or_speed(family: str) -> None:
    for params in param_grid(family):
        caps = everyday([act(family, **params)])
        said = " | ".join(caps)
        assert all(not re.search(r"[<>]|\bHIS\b|\s,|\s\s", c) for c in caps), said
        for key, value in params.items():
            if key in ("side", "hand", "leg") and value in ("left", "right"):
                other = "right" if value == "left" else "left"
                wrong_turn = r"\bclockwise" if value == "left" else "counterclockwise"
                assert not re.search(rf"\b{other}\b|{wrong_turn}", said), (params, said)
            elif key == "hand":  # both: no single side named
                assert not re.search(r"\b(left|right)\b", said), said
            elif key in ("count", "steps"):
                assert all(counts_said(c) <= {value} for c in caps), (params, said)
            elif key == "speed" and family == "walk":
                fast = sum(bool(re.search(r"quick|(?<!without )hurr|speed|march|stride", c))
                           for c in caps)
                slow = sum(bool(re.search(r"slow|easy|without hurrying|gently|amble|wander|"
                                          r"stroll", c)) for c in caps)
                assert (slow > 0, fast > 0) == {"slow": (True, False), "normal": (False, False),
                                                "fast": (False, True)}[value], (params, said)
            elif key == "angle":
                numbers = {int(n) for n in re.findall(r"\b(45|90|135|180)\b", said)}
                assert numbers <= {value}, (params, said)
        if family == "walk_backward":
            assert all(re.search(r"back|retreat", c) for c in caps), said
        if family in ("walk", "jog", "run"):
            assert not re.search(r"\bback", said), said


def test_everyday_words_differ_from_the_benchmarks() -> None:
    rng = np.random.default_rng(0)
    made = set()
    for _ in range(500):
        actions, concurrent = random_motion(rng)
        made.update(describe(actions, rng, concurrent=concurrent, vocabulary=EVERYDAY))
        bench = describe(actions, rng, concurrent=concurrent)
        assert not made & set(bench)
    used = {w for c in made for w in re.findall(r"[a-z]+", c)}
    new_verbs = {v for v in EVERYDAY_VERBS if {v, *FORMS[v]} & used}
    assert len(new_verbs) >= 30, sorted(new_verbs)  # the point: words the benchmark lacks
    assert all(set(FORMS[v]).isdisjoint(BENCHMARK_WORDS) or v in VERB_FORMS for v in new_verbs)


def test_heldout_paraphrases_use_none_of_the_new_verbs() -> None:
    prompts = json.loads(HELDOUT.read_text(encoding="utf-8"))["paraphrases"]
    assert len(prompts) >= 40
    new_words = {w for v in EVERYDAY_VERBS for w in (v, *FORMS[v])} - BENCHMARK_WORDS - {
        "head"}  # "above the head": the benchmark's noun, not the verb "to head"
    for prompt in prompts:
        words = set(re.findall(r"[a-z]+", prompt["text"]))
        assert not words & new_words, prompt["text"]
        assert prompt["actions"] and all(a["family"] in FAMILIES for a in prompt["actions"])


def make_benchmark(root: Path) -> Path:
    from mlct.data.synth.build import synthesize_dataset

    synthesize_dataset(root / "synth", num=12, seed=0, progress=False)
    return root / "synth"


def test_rephrase_adds_captions_to_train_only_and_keeps_the_rest(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    summary = rephrase_dataset(src, tmp_path / "rich", per_motion=2)
    src_layout, rich = DatasetLayout.existing(src), DatasetLayout.existing(tmp_path / "rich")
    train = src_layout.read_split("train")
    assert summary == {"motions": len(train), "captions": 2 * len(train)}
    for name in src_layout.read_split("all"):
        old = [t.caption for t in src_layout.read_texts(name)]
        new = [t.caption for t in rich.read_texts(name)]
        assert new[: len(old)] == old
        assert len(new) == len(old) + (2 if name in train else 0)
        np.testing.assert_array_equal(rich.load_features(name), src_layout.load_features(name))
    for f in ("Mean.npy", "Std.npy", "labels.jsonl", "train.txt", "test.txt"):
        assert (tmp_path / "rich" / f).read_bytes() == (src / f).read_bytes()
    meta = json.loads((tmp_path / "rich" / "synth.json").read_text())
    assert meta["rephrased"]["captions_added"] == 2 * len(train)
    line = (tmp_path / "rich" / "texts" / f"{train[0]}.txt").read_text().splitlines()[-1]
    assert parse_text_line(line).tokens  # HumanML3D's caption#tokens#start#end


def test_rephrase_skips_the_families_asked(tmp_path: Path) -> None:
    from mlct.data.labels import read_labels

    src = make_benchmark(tmp_path)
    labels = read_labels(src)
    train = DatasetLayout.existing(src).read_split("train")
    families = {name: {a["family"] for a in labels[name]["actions"]} for name in train}
    skipped = families[train[0]]
    summary = rephrase_dataset(src, tmp_path / "rich", per_motion=1, skip_families=tuple(skipped))
    kept = [name for name in train if not families[name] & skipped]
    assert summary["motions"] == len(kept) < len(train)
    src_layout, rich = DatasetLayout.existing(src), DatasetLayout.existing(tmp_path / "rich")
    for name in train:
        grew = len(rich.read_texts(name)) - len(src_layout.read_texts(name))
        assert grew == (1 if name in kept else 0), name
    meta = json.loads((tmp_path / "rich" / "synth.json").read_text())
    assert meta["rephrased"]["skip_families"] == sorted(skipped)
    with pytest.raises(MlctError, match="unknown family 'tunr'"):
        rephrase_dataset(src, tmp_path / "bad", skip_families=("tunr",))
    assert not (tmp_path / "bad").exists()


def test_rephrase_refuses_bad_input_and_leaves_nothing(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    with pytest.raises(MlctError, match="split 'nope'"):
        rephrase_dataset(src, tmp_path / "rich", splits=("nope",))
    with pytest.raises(MlctError, match="per-motion"):
        rephrase_dataset(src, tmp_path / "rich", per_motion=0)
    with pytest.raises(MlctError, match="must differ"):
        rephrase_dataset(src, src)
    (src / "labels.jsonl").rename(tmp_path / "labels.jsonl")
    with pytest.raises(MlctError, match="labels.jsonl"):
        rephrase_dataset(src, tmp_path / "rich")
    assert not (tmp_path / "rich").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".rich")]


def test_cli_rephrase_exit_codes(tmp_path: Path) -> None:
    src = make_benchmark(tmp_path)
    run = [sys.executable, "-m", "mlct.cli", "data", "rephrase", str(src), "--out"]
    ok = subprocess.run(run + [str(tmp_path / "rich")], capture_output=True, text=True)
    assert ok.returncode == 0 and "everyday captions added" in ok.stdout
    again = subprocess.run(run + [str(tmp_path / "rich")], capture_output=True, text=True)
    assert again.returncode == 2 and "exists" in again.stderr and "Traceback" not in again.stderr
