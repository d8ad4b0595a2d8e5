"""The text-motion matching evaluator: official checkpoint layout, embeddings, word vectors."""

from __future__ import annotations

import pickle
from collections import OrderedDict

import numpy as np
import pytest
import torch

from mlct.errors import MlctError
from mlct.eval import POS_ENUMERATOR, Evaluator, WordVectorizer
from mlct.motion.skeleton import HUMANML3D, KIT

WORDS = ["sos", "eos", "unk", "a", "man", "walk", "left", "quickly", "chair", "forward"]


def official_shapes(feature_dim: int) -> dict[str, dict[str, tuple[int, ...]]]:
    """finest.tar's state-dict layout, written out from text-to-motion networks/modules.py."""

    def gru(prefix: str, inp: int, hid: int) -> dict[str, tuple[int, ...]]:
        shapes = {}
        for suffix in ("", "_reverse"):
            shapes |= {f"{prefix}weight_ih_l0{suffix}": (3 * hid, inp),
                       f"{prefix}weight_hh_l0{suffix}": (3 * hid, hid),
                       f"{prefix}bias_ih_l0{suffix}": (3 * hid,),
                       f"{prefix}bias_hh_l0{suffix}": (3 * hid,)}
        return shapes

    def head(hid: int) -> dict[str, tuple[int, ...]]:
        return {"output_net.0.weight": (hid, 2 * hid), "output_net.0.bias": (hid,),
                "output_net.1.weight": (hid,), "output_net.1.bias": (hid,),
                "output_net.3.weight": (512, hid), "output_net.3.bias": (512,)}

    return {
        "movement_encoder": {"main.0.weight": (512, feature_dim - 4, 4), "main.0.bias": (512,),
                             "main.3.weight": (512, 512, 4), "main.3.bias": (512,),
                             "out_net.weight": (512, 512), "out_net.bias": (512,)},
        "text_encoder": {"hidden": (2, 1, 512), "pos_emb.weight": (300, 15),
                         "pos_emb.bias": (300,), "input_emb.weight": (512, 300),
                         "input_emb.bias": (512,), **gru("gru.", 512, 512), **head(512)},
        "motion_encoder": {"hidden": (2, 1, 1024), "input_emb.weight": (1024, 512),
                           "input_emb.bias": (1024,), **gru("gru.", 1024, 1024), **head(1024)},
    }


def official_state(feature_dim: int, seed: int = 0) -> dict:
    """A finest.tar-like dict with random weights of the real shapes (as the trainer saves)."""
    gen = torch.Generator().manual_seed(seed)
    state: dict = {}
    for net, shapes in official_shapes(feature_dim).items():
        tensors = OrderedDict()
        for name, shape in shapes.items():
            base = 1.0 if name == "output_net.1.weight" else 0.0  # LayerNorm gain near 1
            scale = 0.1 if len(shape) > 1 else 0.02
            tensors[name] = base + scale * torch.randn(shape, generator=gen)
        state[net] = tensors
    state |= {"opt_text_encoder": {"state": {}, "param_groups": [{"lr": 1e-4, "params": [0]}]},
              "epoch": 37, "iter": 1234}
    return state


@pytest.fixture(scope="module")
def glove_dir(tmp_path_factory):
    directory = tmp_path_factory.mktemp("glove")
    vectors = np.random.default_rng(0).normal(size=(len(WORDS), 300)).astype(np.float32)
    np.save(directory / "our_vab_data.npy", vectors)
    with open(directory / "our_vab_words.pkl", "wb") as f:
        pickle.dump(WORDS, f)
    with open(directory / "our_vab_idx.pkl", "wb") as f:
        pickle.dump({w: i for i, w in enumerate(WORDS)}, f)
    return directory


@pytest.fixture(scope="module")
def official_dir(tmp_path_factory):
    """A HumanML3D checkpoint tree as the download has it: t2m/text_mot_match/model/finest.tar."""
    root = tmp_path_factory.mktemp("t2m")
    (root / "text_mot_match" / "model").mkdir(parents=True)
    torch.save(official_state(HUMANML3D.feature_dim), root / "text_mot_match/model/finest.tar")
    return root


def stats(dim: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=dim).astype(np.float32), rng.uniform(0.5, 2.0, dim).astype(np.float32)


@pytest.fixture(scope="module")
def evaluator(official_dir, glove_dir):
    mean, std = stats(HUMANML3D.feature_dim)
    return Evaluator.load_official(official_dir, glove_dir, mean, std, HUMANML3D.feature_dim)


def motions_batch(dim: int, lengths: list[int], frames: int, seed: int = 2):
    gen = torch.Generator().manual_seed(seed)
    motions = torch.randn(len(lengths), frames, dim, generator=gen)
    for i, length in enumerate(lengths):
        motions[i, length:] = 0.0  # zero padding, as the protocol's loaders
    return motions, torch.tensor(lengths)


# ------------------------------------------------------------------------------ loading

def test_load_official_is_strict_and_keeps_the_weights(evaluator, official_dir):
    state = torch.load(official_dir / "text_mot_match/model/finest.tar", weights_only=True)
    for net, module in evaluator.networks().items():
        loaded = module.state_dict()
        assert set(loaded) == set(state[net])
        for name, tensor in state[net].items():
            torch.testing.assert_close(loaded[name], tensor, rtol=0, atol=0)
    assert evaluator.epoch == 37 and evaluator.feature_dim == 263
    assert all(not m.training for m in evaluator.networks().values())


def save_variant(tmp_path, feature_dim: int, edit) -> str:
    state = official_state(feature_dim)
    edit(state)
    path = tmp_path / "finest.tar"
    torch.save(state, path)
    return str(path)


def one_line_error(path, match: str, feature_dim: int = 263) -> None:
    mean, std = stats(feature_dim)
    with pytest.raises(MlctError, match=match) as info:
        Evaluator.load_official(path, None, mean, std, feature_dim)
    assert "\n" not in str(info.value)


def test_a_renamed_key_is_named(tmp_path):
    def rename(state):
        state["text_encoder"]["pos_embedding.weight"] = state["text_encoder"].pop("pos_emb.weight")
    one_line_error(save_variant(tmp_path, 263, rename), r"text_encoder\.pos_emb\.weight is missing")


def test_an_extra_key_is_named(tmp_path):
    def extra(state):
        state["text_encoder"]["bogus"] = torch.zeros(1)
    one_line_error(save_variant(tmp_path, 263, extra), r"unexpected key text_encoder\.bogus")


def test_a_wrong_shape_is_named(tmp_path):
    def reshape(state):
        state["text_encoder"]["pos_emb.weight"] = torch.zeros(300, 16)
    one_line_error(save_variant(tmp_path, 263, reshape),
                   r"text_encoder\.pos_emb\.weight has shape \(300, 16\), expected \(300, 15\)")


def test_a_kit_checkpoint_with_humanml3d_stats_says_so(tmp_path):
    path = save_variant(tmp_path, KIT.feature_dim, lambda state: None)
    one_line_error(path, r"movement_encoder\.main\.0\.weight .*251-d")


@pytest.mark.slow
def test_missing_entries_and_unreadable_files(tmp_path):
    one_line_error(save_variant(tmp_path, 263, lambda s: s.pop("motion_encoder")),
                   "'motion_encoder' is missing")
    (tmp_path / "garbage.tar").write_bytes(b"not a checkpoint")
    one_line_error(tmp_path / "garbage.tar", "not a readable weights-only")
    one_line_error(tmp_path / "nowhere", "no evaluator checkpoint")
    with pytest.raises(MlctError, match="mean/std"):  # official files carry no statistics
        Evaluator.load_official(save_variant(tmp_path, 263, lambda s: None), None)


def test_save_round_trips_in_the_official_layout(evaluator, glove_dir, tmp_path):
    path = tmp_path / "mine" / "finest.tar"
    evaluator.save(path)
    state = torch.load(path, weights_only=True)
    for net, shapes in official_shapes(263).items():
        assert {k: tuple(v.shape) for k, v in state[net].items()} == shapes
    assert state["epoch"] == 37
    again = Evaluator.load_official(path.parent, glove_dir)  # mean/std read from the file
    torch.testing.assert_close(again.mean, evaluator.mean)
    torch.testing.assert_close(again.std, evaluator.std)
    motions, lengths = motions_batch(263, [40, 24], 40)
    torch.testing.assert_close(again.embed_motion(motions, lengths),
                               evaluator.embed_motion(motions, lengths))


# --------------------------------------------------------------------------- embeddings

def test_motion_embeddings_are_in_input_order(evaluator):
    lengths = [40, 64, 28, 52, 44]  # unsorted on purpose: the reference would sort them
    motions, m_lens = motions_batch(263, lengths, 64)
    emb = evaluator.embed_motion(motions, m_lens)
    assert emb.shape == (5, 512) and torch.isfinite(emb).all()
    perm = torch.tensor([3, 0, 4, 2, 1])
    torch.testing.assert_close(evaluator.embed_motion(motions[perm], m_lens[perm]), emb[perm],
                               rtol=1e-4, atol=1e-5)
    single = torch.cat([evaluator.embed_motion(motions[i:i + 1, :n], m_lens[i:i + 1])
                        for i, n in enumerate(lengths)])
    # Another batch shape runs other float32 kernels: ~3e-5 apart on some AVX-512 CPUs. A mixed-up
    # order or a padding leak moves embeddings by orders of magnitude more.
    torch.testing.assert_close(single, emb, rtol=1e-3, atol=1e-4)
    assert not torch.allclose(emb[0], emb[1], atol=1e-3)  # different motions, different codes


def test_frames_past_the_length_do_not_matter(evaluator):
    motions, m_lens = motions_batch(263, [42, 30], 60)
    clean = evaluator.embed_motion(motions, m_lens)
    noisy = motions.clone()
    noisy[0, 42:] = 5.0
    noisy[1, 30:] = torch.randn(30, 263)
    torch.testing.assert_close(evaluator.embed_motion(noisy, m_lens), clean, rtol=0, atol=1e-6)
    torch.testing.assert_close(evaluator.embed_motion(noisy[1:, :30], m_lens[1:]), clean[1:],
                               rtol=1e-3, atol=1e-4)  # another batch shape: see above


def test_motion_input_is_checked(evaluator):
    motions, m_lens = motions_batch(263, [40, 40], 40)
    with pytest.raises(MlctError, match=r"\(B, T, 263\)"):
        evaluator.embed_motion(motions[..., :251], m_lens)
    with pytest.raises(MlctError, match="m_lens"):
        evaluator.embed_motion(motions, torch.tensor([40, 3]))
    with pytest.raises(MlctError, match="m_lens"):
        evaluator.embed_motion(motions, torch.tensor([40, 41]))
    long_motions, long_lens = motions_batch(263, [200, 40], 200)
    with pytest.raises(MlctError, match="at most 196 frames"):
        evaluator.embed_motion(long_motions, long_lens)
    # A buffer longer than 196 frames is fine while the motions fit in 196.
    long_lens = torch.tensor([196, 40])
    torch.testing.assert_close(evaluator.embed_motion(long_motions, long_lens),
                               evaluator.embed_motion(long_motions[:, :196], long_lens))


def test_motion_embeddings_follow_the_reference_procedure(evaluator):
    # The reference wrapper: zero-padded 196-frame batch sorted by length (longest first),
    # movement encoder on all but the last 4 features, motion encoder on m_lens // 4.
    motions, m_lens = motions_batch(263, [196, 44, 192, 64, 41], 196)
    order = torch.argsort(m_lens, descending=True)
    with torch.no_grad():
        movements = evaluator.movement_encoder(motions[order][..., :-4])
        expected = evaluator.motion_encoder(movements, m_lens[order] // 4)
    torch.testing.assert_close(evaluator.embed_motion(motions, m_lens)[order], expected,
                               rtol=1e-4, atol=1e-5)


def test_text_embeddings_from_tokens_in_input_order(evaluator):
    sentences = [["a/DET", "man/NOUN", "walk/VERB", "forward/ADV"],
                 ["a/DET", "man/NOUN", "walk/VERB", "quickly/ADV", "left/ADV", "chair/NOUN"],
                 ["walk/VERB"]]
    framed = [["sos/OTHER", *s, "eos/OTHER"] for s in sentences]
    cap_lens = [len(t) for t in framed]  # 6, 8, 3: not sorted
    padded = [t + ["unk/OTHER"] * (22 - len(t)) for t in framed]
    words, pos = evaluator.tokens_to_tensors(padded)
    assert words.shape == (3, 22, 300) and pos.shape == (3, 22, 15)
    emb = evaluator.embed_text(words, pos, cap_lens)
    assert emb.shape == (3, 512) and torch.isfinite(emb).all()
    perm = [2, 0, 1]
    torch.testing.assert_close(
        evaluator.embed_text(words[perm], pos[perm], [cap_lens[i] for i in perm]), emb[perm],
        rtol=1e-4, atol=1e-5)
    # Unpadded lists are padded with unk/OTHER; what lies past cap_len does not matter.
    short_words, short_pos = evaluator.tokens_to_tensors(framed)
    assert short_words.shape == (3, 8, 300)
    torch.testing.assert_close(evaluator.embed_text(short_words, short_pos, cap_lens), emb,
                               rtol=1e-4, atol=1e-5)


def test_kit_shapes(tmp_path, glove_dir):
    torch.save(official_state(KIT.feature_dim, seed=3), tmp_path / "finest.tar")
    mean, std = stats(KIT.feature_dim)
    kit = Evaluator.load_official(tmp_path / "finest.tar", glove_dir, mean, std, KIT.feature_dim)
    assert kit.movement_encoder.main[0].weight.shape == (512, 247, 4)
    motions, m_lens = motions_batch(KIT.feature_dim, [32, 48], 48)
    assert kit.embed_motion(kit.normalize(motions), m_lens).shape == (2, 512)


# ------------------------------------------------------------------------- word vectors

def test_word_vectorizer_rules(glove_dir):
    vectorizer = WordVectorizer(glove_dir)
    vectors = np.load(glove_dir / "our_vab_data.npy")

    def pos_of(token):
        onehot = vectorizer[token][1]
        assert onehot.shape == (15,) and onehot.sum() == 1.0
        return next(k for k, v in POS_ENUMERATOR.items() if v == int(onehot.argmax()))

    assert len(vectorizer) == len(WORDS) and len(POS_ENUMERATOR) == 15
    np.testing.assert_array_equal(vectorizer["man/NOUN"][0], vectors[WORDS.index("man")])
    assert pos_of("man/NOUN") == "NOUN"
    # Unknown word: the unk vector and OTHER, whatever its tag.
    np.testing.assert_array_equal(vectorizer["zebra/NOUN"][0], vectors[WORDS.index("unk")])
    assert pos_of("zebra/NOUN") == "OTHER"
    # VIP words take their class over the tagger's.
    assert pos_of("walk/NOUN") == "Act_VIP"
    assert pos_of("left/ADV") == "Loc_VIP"
    assert pos_of("quickly/ADV") == "Desc_VIP"
    assert pos_of("chair/NOUN") == "Obj_VIP"
    # A tag outside the 15 classes is OTHER; the framing tokens are OTHER too.
    assert pos_of("a/PUNCT") == "OTHER"
    assert pos_of("sos/OTHER") == "OTHER"
    with pytest.raises(MlctError, match="word/POS"):
        vectorizer["man"]


def test_word_vectorizer_files_are_checked(glove_dir, tmp_path):
    for name in ("our_vab_data.npy", "our_vab_words.pkl"):
        (tmp_path / name).write_bytes((glove_dir / name).read_bytes())
    with pytest.raises(MlctError, match=r"our_vab_idx\.pkl: missing.*GloVe"):
        WordVectorizer(tmp_path)
    # A pickle that references any class is refused: unpickling could run code.
    with open(tmp_path / "our_vab_idx.pkl", "wb") as f:
        pickle.dump(OrderedDict((w, i) for i, w in enumerate(WORDS)), f)
    with pytest.raises(MlctError, match="not a plain pickled"):
        WordVectorizer(tmp_path)


@pytest.mark.slow
def test_official_files_import_to_an_evaluator_dir_unchanged(official_dir, glove_dir, evaluator,
                                                             tmp_path):
    from mlct.cli import main
    from mlct.eval.judge.evaluator_dir import import_official_evaluator, load_evaluator_dir

    mean, std = stats(HUMANML3D.feature_dim)
    np.save(tmp_path / "mean.npy", mean)
    np.save(tmp_path / "std.npy", std)
    out = import_official_evaluator(official_dir, tmp_path / "mean.npy", tmp_path / "std.npy",
                                    glove_dir, tmp_path / "ev")
    loaded = load_evaluator_dir(out)
    motions, lengths = motions_batch(HUMANML3D.feature_dim, [40, 64], 64)
    assert torch.equal(loaded.embed_motion(motions, lengths),
                       evaluator.embed_motion(motions, lengths))
    assert np.array_equal(loaded.vectorizer["man/NOUN"][0], evaluator.vectorizer["man/NOUN"][0])
    # the command line does the same, and a KIT-width mean is refused in one line
    assert main(["import-evaluator", "--checkpoint", str(official_dir), "--mean",
                 str(tmp_path / "mean.npy"), "--std", str(tmp_path / "std.npy"), "--glove",
                 str(glove_dir), "--out", str(tmp_path / "ev2")]) == 0
    kit_mean, kit_std = stats(KIT.feature_dim)
    np.save(tmp_path / "kmean.npy", kit_mean)
    np.save(tmp_path / "kstd.npy", kit_std)
    assert main(["import-evaluator", "--checkpoint", str(official_dir), "--mean",
                 str(tmp_path / "kmean.npy"), "--std", str(tmp_path / "kstd.npy"), "--glove",
                 str(glove_dir), "--out", str(tmp_path / "ev3")]) == 2
    assert not (tmp_path / "ev3").exists()
