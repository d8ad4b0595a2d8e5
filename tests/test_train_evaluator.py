"""Training the text-motion matching evaluator: both stages, the saved directory, learned words."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from mlct.data.dataset import Text2MotionEvalDataset, collate
from mlct.data.synth.build import synthesize_dataset
from mlct.errors import MlctError
from mlct.eval import Evaluator, euclidean_distance_matrix, r_precision_batched
from mlct.eval.judge.evaluator_dir import EvaluatorSizes, build_networks, load_evaluator_dir
from mlct.eval.judge.learned_words import LearnedWordVectors, build_vocabulary
from mlct.eval.judge.train_evaluator import (
    EvaluatorTrainConfig,
    MovementConvDecoder,
    evaluator_mean_std,
    matching_loss,
    train_evaluator,
)
from mlct.eval.judge.word_vectors import POS_ENUMERATOR
from mlct.motion.skeleton import HUMANML3D

# Small widths and a 10x learning rate: the real sizes take seconds per step on a CPU.
TINY = EvaluatorTrainConfig(
    sizes=EvaluatorSizes(word=32, movement_hidden=64, movement_latent=64, text_hidden=64,
                         motion_hidden=64, embedding=64),
    decomp_batch_size=32, decomp_lr=1e-3, match_lr=1e-3, val_every=20)
STEPS = {"steps_decomp": 5, "steps_match": 60}
POS_NAMES = {index: name for name, index in POS_ENUMERATOR.items()}


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    """48 procedural motions: 38 train (one whole-clip item each), 2 val, 8 test."""
    out = tmp_path_factory.mktemp("synth") / "data"
    synthesize_dataset(out, num=48, seed=0, progress=False)
    return out


@pytest.fixture(scope="module")
def trained(data_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("evaluator") / "ev"
    return train_evaluator(data_dir, out, seed=0, progress=False, config=TINY, **STEPS)


def train_items(evaluator: Evaluator, data_dir) -> dict:
    """Every train item once (a seeded caption and crop), normalized by the evaluator's stats."""
    dataset = Text2MotionEvalDataset(data_dir, "train", mean=evaluator.mean.numpy(),
                                     std=evaluator.std.numpy(), seed=0)
    return collate([dataset[i] for i in range(len(dataset))])


def embed(evaluator: Evaluator, batch: dict) -> tuple[np.ndarray, np.ndarray]:
    words, pos = evaluator.tokens_to_tensors(batch["tokens"])
    text = evaluator.embed_text(words, pos, batch["sent_len"])
    motion = evaluator.embed_motion(batch["motion"], batch["length"])
    return text.numpy(), motion.numpy()


@pytest.mark.slow
def test_the_contrastive_loss_decreases(trained):
    losses = np.array(trained["match_losses"])
    assert len(losses) == STEPS["steps_match"] and np.isfinite(losses).all()
    assert losses[-10:].mean() < 0.7 * losses[:10].mean()
    assert len(trained["decomp_losses"]) == STEPS["steps_decomp"]
    assert np.isfinite(trained["decomp_losses"]).all()
    # Validation every 20 steps on the 2 val motions; the kept weights are the best checked.
    assert sorted(trained["val_losses"]) == list(range(20, 61, 20))
    best = min(trained["val_losses"], key=trained["val_losses"].get)
    assert trained["best_step"] == best
    assert trained["train_items"] == 38 and trained["val_items"] == 2


@pytest.mark.slow
def test_the_directory_is_self_contained_and_reloads_identically(trained, data_dir):
    out = Path(trained["path"])
    names = {p.name for p in out.iterdir()}
    assert names == {"finest.tar", "decomp.tar", "meta.json", "Mean.npy", "Std.npy",
                     "learned_words.npz"}
    meta = json.loads((out / "meta.json").read_text())
    assert meta["feature_dim"] == 263 and meta["vocabulary"] == "learned"
    assert meta["sizes"] == vars(TINY.sizes)
    assert meta["training"]["best_step"] == trained["best_step"]

    reloaded = load_evaluator_dir(out)
    batch = train_items(reloaded, data_dir)
    for got, want in zip(embed(reloaded, batch), embed(trained["evaluator"], batch)):
        np.testing.assert_array_equal(got, want)
    # The evaluator's statistics: the dataset's, root and foot-contact std divided by 5.
    mean, std = np.load(data_dir / "Mean.npy"), np.load(data_dir / "Std.npy")
    np.testing.assert_allclose(reloaded.mean.numpy(), mean)
    np.testing.assert_allclose(reloaded.std.numpy()[4:-4], std[4:-4])
    np.testing.assert_allclose(reloaded.std.numpy()[:4], std[:4] / 5, rtol=1e-6)
    np.testing.assert_allclose(reloaded.std.numpy()[-4:], std[-4:] / 5, rtol=1e-6)
    # The training vocabulary, with the learned vectors.
    assert isinstance(reloaded.vectorizer, LearnedWordVectors)
    assert reloaded.vectorizer.words[:3] == ["unk", "sos", "eos"]
    assert "walk" in reloaded.vectorizer.words


@pytest.mark.slow
def test_matched_pairs_are_closer_after_training(trained, data_dir):
    evaluator = load_evaluator_dir(trained["path"])
    text, motion = embed(evaluator, train_items(evaluator, data_dir))
    dist = euclidean_distance_matrix(text, motion)
    off_diagonal = ~np.eye(len(dist), dtype=bool)
    assert np.diag(dist).mean() < dist[off_diagonal].mean()
    top3 = r_precision_batched(text, motion)[2]
    assert top3 > 2 * 3 / 32  # chance is 3/32 in a group of 32


@pytest.mark.slow
def test_training_is_deterministic_under_the_seed(data_dir, tmp_path):
    config = EvaluatorTrainConfig(sizes=TINY.sizes, decomp_batch_size=8, val_every=2)
    runs = [train_evaluator(data_dir, tmp_path / name, seed=seed, steps_decomp=2, steps_match=3,
                            config=config, progress=False)
            for name, seed in (("a", 1), ("b", 1), ("c", 2))]
    assert runs[0]["match_losses"] == runs[1]["match_losses"]
    assert runs[0]["decomp_losses"] == runs[1]["decomp_losses"]
    assert runs[0]["match_losses"] != runs[2]["match_losses"]
    a, b = (torch.load(tmp_path / n / "finest.tar", weights_only=True) for n in "ab")
    for key in ("text_encoder", "movement_encoder", "motion_encoder"):
        for name, tensor in a[key].items():
            assert torch.equal(tensor, b[key][name]), f"{key}.{name}"
    words = [np.load(tmp_path / n / "learned_words.npz")["vectors"] for n in "ab"]
    np.testing.assert_array_equal(*words)
    # The word table is trained jointly: 0 steps keeps its initial rows. Row 0 (unk) only
    # pads, which the packed GRU never reads, so it keeps its initial value.
    untrained = train_evaluator(data_dir, tmp_path / "d", seed=1, steps_decomp=0, steps_match=0,
                                config=config, progress=False)["evaluator"].vectorizer.vectors
    assert not np.allclose(words[0][1:], untrained[1:], atol=1e-6, rtol=0)
    np.testing.assert_array_equal(words[0][0], untrained[0])


def test_glove_vectors_are_fixed_and_copied(data_dir, tmp_path):
    dataset = Text2MotionEvalDataset(data_dir, "train", seed=0)
    words = [w for w in build_vocabulary(r.tokens for item in dataset.items
                                         for r in item.captions) if w != "walk"]
    vectors = np.random.default_rng(0).normal(size=(len(words), 300)).astype(np.float32)
    glove = tmp_path / "glove"
    glove.mkdir()
    np.save(glove / "our_vab_data.npy", vectors)
    (glove / "our_vab_words.pkl").write_bytes(pickle.dumps(words))
    (glove / "our_vab_idx.pkl").write_bytes(pickle.dumps({w: i for i, w in enumerate(words)}))
    config = EvaluatorTrainConfig(sizes=EvaluatorSizes(**(vars(TINY.sizes) | {"word": 300})),
                                  decomp_batch_size=8)
    summary = train_evaluator(data_dir, tmp_path / "ev", glove_dir=glove, steps_decomp=1,
                              steps_match=2, config=config, progress=True)
    assert summary["vocabulary"] == "glove" and summary["vocabulary_size"] == len(words)
    shutil.rmtree(glove)  # the directory carries its own copy
    evaluator = load_evaluator_dir(tmp_path / "ev")
    assert (tmp_path / "ev" / "glove" / "our_vab_data.npy").is_file()
    np.testing.assert_array_equal(evaluator.vectorizer["man/NOUN"][0], vectors[words.index("man")])
    # A word outside the GloVe vocabulary reads as unk/OTHER.
    np.testing.assert_array_equal(evaluator.vectorizer["walk/VERB"][0],
                                  vectors[words.index("unk")])
    text, motion = embed(evaluator, train_items(evaluator, data_dir))
    assert text.shape == motion.shape == (38, 64)
    with pytest.raises(MlctError, match="300-d"):
        train_evaluator(data_dir, tmp_path / "x", glove_dir=tmp_path / "ev" / "glove",
                        config=TINY, progress=False)


def test_bad_inputs_fail_in_one_line(data_dir, tmp_path):
    def fails(match, source=data_dir, out=None, **kwargs):
        with pytest.raises(MlctError, match=match) as info:
            train_evaluator(source, out or tmp_path / "out", progress=False,
                            **{"steps_decomp": 1, "steps_match": 1, "config": TINY} | kwargs)
        assert "\n" not in str(info.value)

    fails("no such directory", source=tmp_path / "nowhere")
    fails("fewer than batch_size 64", batch_size=64)
    fails("at least 2", batch_size=1)
    fails(">= 0", steps_match=-1)
    fails("our_vab_data.npy", glove_dir=tmp_path, config=EvaluatorTrainConfig())
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "file").write_text("x")
    fails("not empty", out=tmp_path / "full")

    broken = tmp_path / "broken"
    shutil.copytree(data_dir, broken)
    (broken / "Mean.npy").unlink()
    fails("Mean.npy: missing", source=broken)
    shutil.copyfile(data_dir / "Mean.npy", broken / "Mean.npy")
    first = (broken / "train.txt").read_text().split()[0]
    np.save(broken / "new_joint_vecs" / f"{first}.npy", np.zeros((60, 100), np.float32))
    fails(f"{first}.npy: 100 features per frame, expected 263", source=broken)
    with pytest.warns(UserWarning, match="skipped 1 bad file"):
        skipped = train_evaluator(broken, tmp_path / "skip", steps_decomp=1, steps_match=1,
                                  config=TINY, progress=False, on_bad_file="skip")
    assert skipped["train_items"] == 37
    shutil.rmtree(broken / "new_joints")
    for path in (broken / "new_joint_vecs").iterdir():  # every file 100-d: no known skeleton
        np.save(path, np.zeros((60, 100), np.float32))
    fails("cannot tell the skeleton", source=broken)
    assert not (tmp_path / "out").exists()  # nothing is written before training succeeds


@pytest.mark.slow
def test_load_evaluator_dir_checks_its_input(trained, tmp_path):
    with pytest.raises(MlctError, match="no meta.json"):
        load_evaluator_dir(tmp_path)
    copy = tmp_path / "copy"
    shutil.copytree(trained["path"], copy)
    (copy / "learned_words.npz").unlink()
    with pytest.raises(MlctError, match="learned_words.npz: missing"):
        load_evaluator_dir(copy)
    meta = json.loads((copy / "meta.json").read_text())
    (copy / "meta.json").write_text(json.dumps(meta | {"sizes": vars(EvaluatorSizes())}))
    with pytest.raises(MlctError, match="shape"):
        load_evaluator_dir(copy)
    (copy / "meta.json").write_text(json.dumps(meta | {"format": "other"}))
    with pytest.raises(MlctError, match="format"):
        load_evaluator_dir(copy)


@pytest.mark.slow
def test_official_sizes_write_an_official_checkpoint(data_dir, tmp_path):
    """Untrained (0 steps) at the reference's sizes: finest.tar loads with load_official."""
    train_evaluator(data_dir, tmp_path / "ev", steps_decomp=0, steps_match=0, progress=False)
    evaluator = Evaluator.load_official(tmp_path / "ev" / "finest.tar", glove_dir=None)
    assert evaluator.feature_dim == 263
    decomp = torch.load(tmp_path / "ev" / "decomp.tar", weights_only=True)
    assert decomp["movement_dec"]["main.2.weight"].shape == (512, 263, 4)  # ConvTranspose1d
    assert decomp["movement_dec"]["out_net.weight"].shape == (263, 263)


def test_learned_word_vectors_follow_the_vectorizer_rules(tmp_path):
    words = build_vocabulary([["a/DET", "man/NOUN", "walk/VERB", "left/ADJ"], ["man/NOUN"]])
    assert words == ["unk", "sos", "eos", "a", "left", "man", "walk"]
    table = LearnedWordVectors.initial(words, dim=8, rng=np.random.default_rng(0))
    vectors, pos = table.encode(["sos/OTHER", "man/NOUN", "left/ADJ", "jump/VERB"])
    np.testing.assert_array_equal(vectors, table.vectors[[1, 5, 4, 0]])  # unknown -> unk
    assert [POS_NAMES[i] for i in pos.argmax(1)] == ["OTHER", "NOUN", "Loc_VIP",
                                                                 "OTHER"]
    ids, pos_ids = table.ids(["sos/OTHER", "man/NOUN", "left/ADJ", "jump/VERB"])
    assert ids.tolist() == [1, 5, 4, 0]
    np.testing.assert_array_equal(pos_ids, pos)
    table.save(tmp_path / "w.npz")
    loaded = LearnedWordVectors.load(tmp_path / "w.npz")
    assert loaded.words == words
    np.testing.assert_array_equal(loaded.vectors, table.vectors)
    with pytest.raises(MlctError, match="word/POS"):
        table.ids(["man"])
    np.save(tmp_path / "bad.npy", np.zeros(3))
    with pytest.raises(MlctError, match="not an mlct learned-words file"):
        LearnedWordVectors.load(tmp_path / "bad.npy")
    with pytest.raises(MlctError, match="'eos'"):
        LearnedWordVectors(["unk", "sos"], np.zeros((2, 4)))


def test_matching_loss_is_the_reference_contrastive_loss():
    text = torch.tensor([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    motion = torch.tensor([[0.0, 2.0], [3.0, 0.0], [0.0, 0.0]])
    d_pos = torch.tensor([2.0, 0.0, 4.0])
    loss_pos, loss_neg = matching_loss(text, motion, ["x", "y", "z"], shift=1, margin=5.0)
    torch.testing.assert_close(loss_pos, (d_pos**2).mean(), atol=1e-4, rtol=0)
    # Text i meets motion i + 1: distances 3, 3, 2 -> (5 - d)^2 = 4, 4, 9.
    torch.testing.assert_close(loss_neg, torch.tensor(17 / 3), atol=1e-4, rtol=0)
    # A negative with the positive's caption is skipped; all skipped gives 0.
    _, loss_neg = matching_loss(text, motion, ["x", "x", "z"], shift=1, margin=5.0)
    torch.testing.assert_close(loss_neg, torch.tensor(6.5), atol=1e-4, rtol=0)
    _, loss_neg = matching_loss(text, motion, ["x", "x", "x"], shift=1, margin=5.0)
    assert loss_neg.item() == 0.0


def test_decoder_and_statistics():
    decoder = MovementConvDecoder(16, 32, 263)
    assert decoder(torch.zeros(2, 10, 16)).shape == (2, 40, 263)
    nets = build_networks(263, TINY.sizes)
    assert nets["movement_encoder"](torch.zeros(2, 40, 259)).shape == (2, 10, 64)
    mean, std = np.zeros(263), np.full(263, 2.0)
    _, scaled = evaluator_mean_std(mean, std, HUMANML3D, feat_bias=5.0)
    assert (scaled[:4] == 0.4).all() and (scaled[-4:] == 0.4).all() and (scaled[4:-4] == 2).all()
    assert std[0] == 2.0  # the input is not modified
