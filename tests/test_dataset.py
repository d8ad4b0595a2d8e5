"""Torch datasets: length filter, sub-clips, cropping, padding, normalization, seeds, bad files."""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest
import torch
from dataset_factory import CAPTIONS, make_dataset

from mlct.data import dataset as dataset_module
from mlct.data.dataset import Text2MotionDataset, Text2MotionEvalDataset, collate
from mlct.errors import MlctError
from mlct.motion.skeleton import KIT

SUB_OK = "a man walks.#a/DET man/NOUN walk/VERB#1.0#3.5"  # frames 20..69: 50 frames, kept
SUB_SHORT = "a man hops.#a/DET man/NOUN hop/VERB#0.5#1.5"  # 20 frames: filtered
LENGTHS = {"000001": 60, "000002": 39, "000003": 199, "000004": 200, "000005": 120,
           "000006": 40}


@pytest.fixture
def root(tmp_path):
    make_dataset(tmp_path, LENGTHS,
                 splits={"train": list(LENGTHS), "test": ["000001"]},
                 captions={"000005": CAPTIONS + [SUB_OK, SUB_SHORT],
                           "000006": [SUB_OK.replace("1.0#3.5", "0.0#1.0")]})
    return tmp_path


def normalized(root, name):
    features = np.load(root / "new_joint_vecs" / f"{name}.npy")
    return (features - np.load(root / "Mean.npy")) / np.load(root / "Std.npy")


def test_length_filter_and_subclip_items(root):
    ds = Text2MotionDataset(root, "train", seed=0)
    names = sorted(ds.name(i) for i in range(len(ds)))
    # 000002 (39) and 000004 (200) are dropped; 000005's line 4 is a sub-clip of its own;
    # 000006 has only a sub-clip caption, 20 frames long: dropped.
    assert names == ["000001", "000003", "000005", "000005#4"]
    assert ds.filtered == 4
    lengths = dict(zip((ds.name(i) for i in range(len(ds))), ds.lengths))
    assert lengths == {"000001": 60, "000003": 199, "000005": 120, "000005#4": 50}
    assert ds.skeleton.name == "humanml3d"


def test_sample_shape_padding_and_normalization(root):
    ds = Text2MotionDataset(root, "train", seed=0)
    for index in range(len(ds)):
        name = ds.name(index)
        reference = normalized(root, name.split("#")[0])
        if name == "000005#4":
            reference = reference[20:70]
        for _ in range(10):
            caption, tokens, motion, length = ds[index]
            assert motion.shape == (196, 263) and motion.dtype == torch.float32
            assert length % 4 == 0
            units = len(reference) // 4
            assert length in (units * 4, (units - 1) * 4)
            assert torch.count_nonzero(motion[length:]) == 0
            # The window is a contiguous crop of the normalized motion.
            window = motion[:length].numpy()
            starts = [s for s in range(len(reference) - length + 1)
                      if np.allclose(reference[s:s + length], window, atol=1e-5)]
            assert starts, f"{name}: the sample is no crop of the normalized motion"
            assert isinstance(caption, str) and all("/" in t for t in tokens)


def test_crop_coin_and_random_start(root):
    ds = Text2MotionDataset(root, "train", seed=1)
    index = [ds.name(i) for i in range(len(ds))].index("000001")  # 60 frames
    lengths = [ds[index].length for _ in range(600)]
    double = lengths.count(56) / len(lengths)
    assert set(lengths) == {60, 56} and 0.25 < double < 0.42  # 1/3 'double'


def test_captions_drawn_from_the_item(root):
    ds = Text2MotionDataset(root, "train", seed=2)
    names = [ds.name(i) for i in range(len(ds))]
    whole = {ds[names.index("000005")].caption for _ in range(60)}
    assert whole == {line.split("#")[0] for line in CAPTIONS}
    assert {ds[names.index("000005#4")].caption for _ in range(10)} == {"a man walks."}


def test_seed_determinism(root):
    def draws(**kwargs):
        ds = Text2MotionDataset(root, "train", **kwargs)
        return [(s.caption, s.length, s.motion.sum().item()) for s in (ds[i % 4]
                                                                     for i in range(40))]

    assert draws(seed=7) == draws(seed=7)
    assert draws(seed=7) != draws(seed=8)
    generator = torch.Generator().manual_seed(7)
    assert draws(generator=generator) == draws(seed=7)


def test_worker_reseeds_from_worker_seed(root, monkeypatch):
    ds = Text2MotionDataset(root, "train", seed=0)
    monkeypatch.setattr(dataset_module, "get_worker_info",
                        lambda: types.SimpleNamespace(seed=123, id=0))
    in_worker = [ds[1].length for _ in range(30)]
    again = Text2MotionDataset(root, "train", seed=99)
    assert [again[1].length for _ in range(30)] == in_worker  # the worker seed decides


def test_kit_subclip_cut_at_kit_fps(tmp_path):
    make_dataset(tmp_path, {"000001": 100}, skeleton=KIT, splits={"train": ["000001"]},
                 captions={"000001": [SUB_OK.replace("1.0#3.5", "1.0#3.3")]})
    ds = Text2MotionDataset(tmp_path, "train", seed=0)
    assert ds.skeleton is KIT and len(ds) == 1
    assert ds.name(0) == "000001#1" and ds.lengths[0] == 41 - 12  # int(41.25) - int(12.5)
    assert ds[0].motion.shape == (196, 251)


def test_strict_names_the_bad_file(root):
    (root / "new_joint_vecs" / "000003.npy").write_bytes(b"broken")
    with pytest.raises(MlctError, match=r"000003\.npy: unreadable"):
        Text2MotionDataset(root, "train")


def test_strict_missing_text(root):
    (root / "texts" / "000001.txt").unlink()
    with pytest.raises(MlctError, match=r"000001\.txt: missing"):
        Text2MotionDataset(root, "train")


def test_skip_warns_once_with_the_count(root):
    (root / "new_joint_vecs" / "000003.npy").write_bytes(b"broken")
    (root / "texts" / "000001.txt").write_text("no fields\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = Text2MotionDataset(root, "train", on_bad_file="skip", seed=0)
    assert len(caught) == 1 and "skipped 2 bad file(s)" in str(caught[0].message)
    assert len(ds.skipped) == 2
    assert sorted(ds.name(i) for i in range(len(ds))) == ["000005", "000005#4"]


def test_clean_split_does_not_warn(root):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Text2MotionDataset(root, "test", seed=0)


def test_usage_errors(root):
    with pytest.raises(MlctError, match="no such split"):
        Text2MotionDataset(root, "val")
    with pytest.raises(ValueError, match="on_bad_file"):
        Text2MotionDataset(root, on_bad_file="ignore")
    (root / "Mean.npy").unlink()
    with pytest.raises(MlctError, match="mlct data stats"):
        Text2MotionDataset(root, "train")
    mean, std = np.zeros(263, np.float32), np.ones(263, np.float32)
    ds = Text2MotionDataset(root, "test", mean=mean, std=std, seed=0)  # explicit stats
    sample = ds[0]
    raw = np.load(root / "new_joint_vecs" / "000001.npy")
    assert any(np.allclose(raw[s:s + sample.length], sample.motion[:sample.length].numpy())
               for s in range(60 - sample.length + 1))
    with pytest.raises(MlctError, match="finite and > 0"):
        Text2MotionDataset(root, "test", mean=mean, std=np.zeros(263, np.float32))
    with pytest.raises(MlctError, match="no motion within the length filter"):
        (root / "empty.txt").write_text("000002\n")
        Text2MotionDataset(root, "empty", mean=mean, std=std)


def test_denormalize_inverts(root):
    ds = Text2MotionDataset(root, "test", seed=0)
    sample = ds[0]
    restored = ds.denormalize(sample.motion[:sample.length])
    raw = torch.from_numpy(np.load(root / "new_joint_vecs" / "000001.npy"))
    assert any(torch.allclose(raw[s:s + sample.length], restored, atol=1e-5)
               for s in range(60 - sample.length + 1))


def test_collate_stacks_and_keeps_lengths(root):
    ds = Text2MotionDataset(root, "train", seed=0)
    loader = torch.utils.data.DataLoader(ds, batch_size=3, collate_fn=collate)
    batch = next(iter(loader))
    assert batch["motion"].shape == (3, 196, 263)
    assert batch["length"].dtype == torch.long and batch["length"].shape == (3,)
    assert len(batch["caption"]) == len(batch["tokens"]) == 3
    for i in range(3):
        assert torch.count_nonzero(batch["motion"][i, batch["length"][i]:]) == 0


def test_eval_variant_tokens_and_sorting(root):
    ds = Text2MotionEvalDataset(root, "train", seed=0, max_text_length=5)
    names = [ds.name(i) for i in range(len(ds))]
    sample = ds[names.index("000005#4")]  # 3 tokens
    assert sample.tokens == ["sos/OTHER", "a/DET", "man/NOUN", "walk/VERB", "eos/OTHER",
                             "unk/OTHER", "unk/OTHER"]
    assert sample.sent_len == 5
    long = ds[names.index("000001")]  # 10 tokens or 9: cropped to 5
    assert len(long.tokens) == 7 and long.sent_len == 7 and long.tokens[-1] == "eos/OTHER"
    batch = collate([sample, long])
    assert batch["sent_len"].tolist() == [7, 5]  # longest text first
    assert batch["tokens"][0] == long.tokens and batch["length"][0] == long.length
