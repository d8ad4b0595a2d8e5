"""Text anchors: far prompts pulled towards the nearest training captions (generate/
compose/text_anchors.py), their file beside a model, `mlct train anchors` (train/text_anchors.py) and
the pipeline sampling from the pulled vector while the critic judges the prompt's own."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F

import mlct
from mlct.data.labels import read_labels
from mlct.data.layout import DatasetLayout
from mlct.errors import MlctError
from mlct.generate.bundle import bundled_model_dir
from mlct.generate.compose.text_anchors import (FILE, TextAnchors, _unit, _unit_columns,
                                                read_text_anchors, save_text_anchors)

pytestmark = pytest.mark.usefixtures("one_thread")


def _anchors(pull: float = 0.5, near: float = 0.9, span: float = 0.2, k: int = 2) -> TextAnchors:
    vectors = torch.tensor([[1.0, 0.0, 0.0], [0.9, 0.1, 0.0], [0.0, 1.0, 0.0],
                            [0.0, 0.9, 0.1], [0.0, 0.0, 2.0]])
    return TextAnchors(vectors, near=near, span=span, pull=pull, neighbours=k)


def test_a_prompt_near_the_captions_is_left_alone_and_a_far_one_is_pulled() -> None:
    anchors = _anchors()
    near_prompt = torch.tensor([[2.0, 0.0, 0.0]])  # cosine 1 with the first anchor
    assert anchors(near_prompt) is near_prompt
    # cosine 1/3 with its nearest anchor: below near - span, so pulled by the whole 0.5
    far = torch.tensor([[-1.0, -1.0, 0.5]])
    nearest = F.normalize(anchors.vectors, dim=1) @ F.normalize(far, dim=1)[0]
    top2 = nearest.topk(2).indices
    expected = 0.5 * far + 0.5 * anchors.vectors[top2].mean(0)
    torch.testing.assert_close(anchors(far), expected)
    # halfway down the span, half the pull: the prompt at cosine 0.8 with the first anchor
    # (and less with every other), near 0.9, span 0.2
    halfway = torch.tensor([[0.8, 0.0, 0.6]])
    best = float((F.normalize(anchors.vectors, dim=1) @ halfway[0]).max())
    assert best == pytest.approx(0.8)
    pull, _ = anchors.weights(halfway)
    assert float(pull[0]) == pytest.approx(0.25)
    # dtype and device stay the caller's
    assert anchors(far.double()).dtype == torch.float64


def test_neighbours_that_all_say_the_same_pull_a_far_prompt_further() -> None:
    """groups: a far prompt whose neighbours share one label is pulled by agreed_pull; one
    whose neighbours differ, or whose labels are mixed (-1), by pull as before."""
    far = torch.tensor([[-1.0, -1.0, 0.5]])
    top = (F.normalize(_anchors().vectors, dim=1) @ F.normalize(far, dim=1)[0]).topk(2).indices
    for groups, expected in (([0, 0, 0, 0, 0], 1.0), ([0, 1, 2, 3, 4], 0.5),
                             ([-1, -1, -1, -1, -1], 0.5)):
        anchors = TextAnchors(_anchors().vectors, near=0.9, span=0.2, pull=0.5, neighbours=2,
                              groups=torch.tensor(groups), agreed_pull=1.0)
        assert float(anchors.weights(far)[0][0]) == pytest.approx(expected)
    # agreement among the two nearest only: give them one group, the rest others
    groups = torch.arange(5)
    groups[top] = 7
    anchors = TextAnchors(_anchors().vectors, 0.9, 0.2, 0.5, 2, groups=groups, agreed_pull=0.8)
    torch.testing.assert_close(anchors(far), 0.2 * far + 0.8 * anchors.vectors[top].mean(0))
    # halfway down the span, half of agreed_pull
    halfway = torch.tensor([[0.8, 0.0, 0.6]])
    same = TextAnchors(_anchors().vectors, 0.9, 0.2, 0.5, 2, groups=torch.zeros(5, dtype=torch.long))
    assert float(same.weights(halfway)[0][0]) == pytest.approx(0.5)
    # a pull of 0 leaves unagreed prompts alone and still pulls agreed ones
    only = TextAnchors(_anchors().vectors, 0.9, 0.2, 0.0, 2, groups=torch.zeros(5, dtype=torch.long))
    assert float(only.weights(far)[0][0]) == pytest.approx(1.0)
    assert float(TextAnchors(_anchors().vectors, 0.9, 0.2, 0.0, 2).weights(far)[0][0]) == 0.0
    with pytest.raises(MlctError, match="groups of shape"):
        TextAnchors(_anchors().vectors, 0.9, 0.2, 0.5, 2, groups=torch.zeros(4))
    with pytest.raises(MlctError, match="agreed_pull must be in"):
        TextAnchors(_anchors().vectors, 0.9, 0.2, 0.5, 2, agreed_pull=1.2)


def test_a_row_seen_before_comes_from_the_memo_which_stays_bounded(monkeypatch) -> None:
    from mlct.generate.compose import text_anchors

    monkeypatch.setattr(text_anchors, "MEMO_ROWS", 3)
    anchors = _anchors()
    far = torch.tensor([[-1.0, -1.0, 0.5], [0.0, -1.0, 0.2]])
    first = anchors(far)
    calls = []
    rule = anchors._rule
    object.__setattr__(anchors, "_rule", lambda c: calls.append(len(c)) or rule(c))
    torch.testing.assert_close(anchors(far), first)
    assert calls == []  # both rows from the memo
    mixed = torch.cat([far[:1], torch.tensor([[0.2, -1.0, 0.0]])])
    torch.testing.assert_close(anchors(mixed)[0], first[0])
    assert calls == [1]  # only the new row computed
    for k in range(5):
        anchors(torch.tensor([[-1.0, float(k), 0.3]]))
    assert len(anchors._memo) == 3


def test_the_unit_columns_are_made_in_blocks_to_the_same_bits() -> None:
    rows = np.random.default_rng(0).standard_normal((1300, 24)).astype(np.float32)
    rows[7] = 0.0  # a zero row stays zero
    for block in (1, 512, 5000):
        columns = _unit_columns(rows, block)
        assert columns.flags.c_contiguous and columns.dtype == np.float32
        assert np.array_equal(columns, np.ascontiguousarray(_unit(rows).T))


def test_the_rule_refuses_what_cannot_work() -> None:
    with pytest.raises(MlctError, match="pull must be in"):
        _anchors(pull=1.5)
    with pytest.raises(MlctError, match="at least 6 vectors"):
        _anchors(k=6)


def test_the_file_round_trips_in_int8_and_refuses_what_does_not_fit(tmp_path: Path) -> None:
    torch.manual_seed(0)
    vectors = torch.randn(40, 384)
    saved = TextAnchors(vectors, near=0.85, span=0.2, pull=0.5, neighbours=5, info={"seed": 3})
    path = save_text_anchors(tmp_path, saved, "minilm+sides")
    assert path.name == FILE and path.stat().st_size < 40 * 384 + 4096  # a byte per number
    loaded = read_text_anchors(tmp_path, "minilm+sides", 384)
    assert loaded is not None and (loaded.near, loaded.span, loaded.pull) == (0.85, 0.2, 0.5)
    assert loaded.neighbours == 5 and loaded.info["seed"] == 3
    # int8 rows with a scale each: every number within half a step of its row's scale
    step = vectors.abs().amax(1, keepdim=True) / 127
    # (read as numpy arrays: the onnx backend runs the rule without torch)
    assert bool(((torch.from_numpy(loaded.vectors) - vectors).abs() <= 0.51 * step + 1e-3).all())
    # saved again with another rule, the file keeps the new rule, not the info's old one
    save_text_anchors(tmp_path, TextAnchors(loaded.vectors, 0.7, 0.1, 0.3, 4, loaded.info),
                      "minilm+sides")
    again = read_text_anchors(tmp_path, "minilm+sides", 384)
    assert (again.near, again.span, again.pull, again.neighbours) == (0.7, 0.1, 0.3, 4)
    assert again.info["seed"] == 3
    assert again.groups is None and again.agreed_pull == 0.3  # no groups: pull everywhere
    # the groups travel as int16, with their pull
    groups = torch.arange(40) % 3 - 1
    save_text_anchors(tmp_path, TextAnchors(loaded.vectors, 0.7, 0.1, 0.3, 4, loaded.info,
                                            groups, 0.9), "minilm+sides")
    grouped = read_text_anchors(tmp_path, "minilm+sides", 384)
    assert torch.equal(torch.from_numpy(grouped.groups), groups) and grouped.agreed_pull == 0.9
    save_text_anchors(tmp_path, TextAnchors(loaded.vectors, 0.7, 0.1, 0.3, 4, grouped.info),
                      "minilm+sides")  # saved again without them: no stale agreed_pull
    assert read_text_anchors(tmp_path, "minilm+sides", 384).agreed_pull == 0.3
    assert read_text_anchors(tmp_path / "none", "minilm+sides", 384) is None
    with pytest.raises(MlctError, match="text encoder 'minilm\\+sides'"):
        read_text_anchors(tmp_path, "minilm", 384)
    with pytest.raises(MlctError, match="384-d"):
        read_text_anchors(tmp_path, "minilm+sides", 512)
    (tmp_path / FILE).write_bytes(b"not safetensors")
    with pytest.raises(MlctError, match="not text anchors"):
        read_text_anchors(tmp_path, "minilm+sides", 384)


@pytest.fixture(scope="module")
def model_and_data(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A copy of the bundled model without anchors, and a tiny benchmark."""
    from mlct.data.synth.build import synthesize_dataset

    root = tmp_path_factory.mktemp("anchors")
    synthesize_dataset(root / "synth", num=60, seed=0, progress=False)
    model = root / "model"
    shutil.copytree(bundled_model_dir(), model, ignore=shutil.ignore_patterns("onnx"))
    (model / FILE).unlink(missing_ok=True)
    return model, root / "synth"


def test_making_keeps_one_action_captions_and_leaves_the_calibration_split_alone(
        model_and_data: tuple[Path, Path]) -> None:
    from mlct.train.text_anchors import make_text_anchors, split_captions

    model, data = model_and_data
    summary = make_text_anchors(data, model, size=1000, log=lambda _: None)
    gen = mlct.load(model, backend="torch")
    anchors = gen.text_anchors
    assert anchors is not None and len(anchors.vectors) == summary["captions"]
    kept = split_captions(data, "train")
    assert summary["captions"] == len(kept) > 0
    labels, layout = read_labels(data), DatasetLayout(data)
    multi = [r.caption.strip() for n in layout.read_split("train")
             if len(labels[n]["actions"]) > 1 for r in layout.read_texts(n)]
    assert multi  # the tiny benchmark has sequences, whose captions stay out
    assert not set(multi) & set(kept)
    # at most 5 % of the validation split's one-action captions are pulled, by construction
    held = split_captions(data, "val")
    pull, _ = anchors.weights(gen.encode_text(held))
    assert float((pull > 0).float().mean()) <= 0.05 + 1.0 / len(held)
    # each caption's group is its motion's label signature: captions of the same signature
    # share a group, and none is mixed in the tiny benchmark
    from mlct.train.text_anchors import SIGNATURE_KEYS

    signature = {}
    for name in layout.read_split("train"):
        if len(labels[name]["actions"]) == 1:
            action = labels[name]["actions"][0]
            sig = (action["family"], *(action["params"].get(k) for k in SIGNATURE_KEYS),
                   (labels[name].get("concurrent") or {}).get("family"))
            for r in layout.read_texts(name):
                signature.setdefault(r.caption.strip(), set()).add(sig)
    groups = anchors.groups.tolist()
    assert anchors.agreed_pull == 1.0 and len(groups) == len(kept)
    for a, b in [(0, i) for i in range(1, len(kept))]:
        same = signature[kept[a]] == signature[kept[b]] and len(signature[kept[a]]) == 1
        assert (groups[a] == groups[b] >= 0) == same
    assert all((g >= 0) == (len(signature[c]) == 1) for g, c in zip(groups, kept))
    # a sample smaller than the captions keeps that many
    make_text_anchors(data, model, size=5, log=lambda _: None)
    assert len(mlct.load(model, backend="torch").text_anchors.vectors) == 5


def test_data_without_labels_gives_anchors_without_groups(model_and_data: tuple[Path, Path],
                                                        tmp_path: Path) -> None:
    """An imported dataset has no labels.jsonl: every caption is kept and none is grouped, so
    far prompts are pulled by `pull` alone, as before groups."""
    from mlct.data.labels import LABELS_FILE
    from mlct.train.text_anchors import make_text_anchors

    model, data = model_and_data
    bare, copy = tmp_path / "data", tmp_path / "model"
    shutil.copytree(data, bare)
    shutil.copytree(model, copy)
    (bare / LABELS_FILE).unlink()
    make_text_anchors(bare, copy, size=50, log=lambda _: None)
    anchors = mlct.load(copy, backend="torch").text_anchors
    assert anchors is not None and anchors.groups is None and "groups" not in anchors.info


def test_a_run_stopped_before_the_end_leaves_the_models_anchors_as_they_were(
        model_and_data: tuple[Path, Path], tmp_path: Path, monkeypatch) -> None:
    from mlct.train import text_anchors as maker

    model, data = model_and_data
    copy = tmp_path / "model"
    shutil.copytree(model, copy)
    maker.make_text_anchors(data, copy, size=20, log=lambda _: None)
    before = (copy / FILE).read_bytes()

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(maker.np, "quantile", stopped)  # the last measurement, before writing
    with pytest.raises(KeyboardInterrupt):
        maker.make_text_anchors(data, copy, size=30, log=lambda _: None)
    assert (copy / FILE).read_bytes() == before
    assert sorted(p.name for p in copy.iterdir()) == sorted(p.name for p in model.iterdir())


def test_the_pipeline_samples_the_pulled_vector_and_the_critic_judges_the_prompt(
        model_and_data: tuple[Path, Path]) -> None:
    model, _ = model_and_data
    gen = mlct.load(model, backend="torch")
    gen.foot_lock = None
    text, frames = "a person walks forward", 40
    target = gen.encode_text(["a person jumps twice"])
    # anchors that pull every prompt the whole way onto one vector
    gen.text_anchors = TextAnchors(target.repeat(5, 1), near=2.0, span=1.0, pull=1.0)
    made = gen.generate(text, lengths=frames, seed=3, candidates=1, split_actions=False)[0]
    (direct,) = gen.decode(gen.sample_latents(target, None, [3]), [frames])
    np.testing.assert_allclose(made.features, direct, atol=1e-4)
    # best of 4: the critic scores the candidates against the prompt's own vector
    seen: list[torch.Tensor] = []
    best = gen.critic.best
    gen.critic.best = lambda z, f, text_emb, n: seen.append(text_emb) or best(z, f, text_emb, n)
    gen.generate(text, lengths=frames, seed=3, candidates=4, split_actions=False)
    torch.testing.assert_close(seen[0], gen.encode_text([text]).float())
    gen.text_anchors = None  # off: the prompt as worded
    plain = gen.generate(text, lengths=frames, seed=3, candidates=1, split_actions=False)[0]
    assert np.abs(plain.features - made.features).max() > 1e-2


def test_cli_train_anchors_names_bad_input(model_and_data: tuple[Path, Path],
                                           tmp_path: Path) -> None:
    model, data = model_and_data
    copy = tmp_path / "model"
    shutil.copytree(model, copy)
    (copy / FILE).unlink(missing_ok=True)
    base = [sys.executable, "-m", "mlct.cli", "train", "anchors", "--data", str(data),
            "--model", str(copy)]
    for flag in ("--pull", "--agreed-pull"):
        bad = subprocess.run(base + [flag, "2"], capture_output=True, text=True)
        assert bad.returncode == 2 and "pull in [0, 1]" in bad.stderr
        assert "Traceback" not in bad.stderr and not (copy / FILE).exists()
    ok = subprocess.run(base + ["--size", "50"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert "text anchors:" in ok.stdout and (copy / FILE).is_file()


def test_the_bundled_model_pulls_a_far_prompt_and_the_cli_can_turn_it_off(tmp_path: Path
                                                                          ) -> None:
    gen = mlct.load(backend="torch")
    assert gen.text_anchors is not None  # the bundle ships them
    far, near = "a courtier sweeps into a low bow", "a person bows"
    pull, _ = gen.text_anchors.weights(gen.encode_text([far, near]))
    assert float(pull[0]) > 0.1 and float(pull[1]) == 0.0
    base = [sys.executable, "-m", "mlct.cli", "generate", far, "--seconds", "2", "--seed", "1",
            "--backend", "torch", "--candidates", "1"]
    runs = {}
    for name, extra in (("pulled", []), ("worded", ["--no-text-anchors"])):
        out = tmp_path / f"{name}.npy"
        done = subprocess.run(base + extra + ["--out", str(out)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        runs[name] = np.load(out)
    # the same seed on the same backend repeats to float noise, so a gap of centimetres is the
    # flag's (7 cm on the bundle of 2026-11-27, 4 cm on the one of 2026-11-28: both bow)
    assert np.abs(runs["pulled"] - runs["worded"]).max() > 0.01  # metres
