"""Text encoders (bundled MiniLM, tiny random CLIP, sentence-transformers dirs) and their cache."""

from __future__ import annotations

import json
import multiprocessing as mp
import string
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
import torch

from mlct.errors import MlctError
from mlct.text import (
    MINILM,
    CachedTextEncoder,
    ClipTextEncoder,
    EmbeddingCache,
    SentenceTransformerEncoder,
    TextEncoder,
    default_cache_dir,
    load_text_encoder,
)
from mlct.text.cache import CACHE_FILENAME

pytest.importorskip("sentence_transformers")
pytest.importorskip("transformers")

WALK = "a person walks forward"
WALK_PARAPHRASE = "someone walks ahead"
CARTWHEEL = "a man does a cartwheel"


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def minilm() -> TextEncoder:
    """The bundled MiniLM, loaded once for the module (the slow part of this file)."""
    return load_text_encoder(MINILM)


def _write_tiny_clip_tokenizer(path: Path) -> None:
    """A hand-made CLIP BPE vocabulary: letters, letters ending a word, and a few merges."""
    vocab = {"<|startoftext|>": 0, "<|endoftext|>": 1}
    for suffix in ("", "</w>"):
        for c in string.ascii_lowercase:
            vocab[c + suffix] = len(vocab)
    merges = [("w", "a"), ("wa", "l"), ("wal", "k</w>"), ("t", "h"), ("th", "e</w>")]
    for a, b in merges:
        vocab[a + b] = len(vocab)
    path.mkdir(parents=True, exist_ok=True)
    (path / "vocab.json").write_text(json.dumps(vocab))
    (path / "merges.txt").write_text("#version: 0.2\n" + "".join(f"{a} {b}\n" for a, b in merges))


def _tiny_text_config(vocab_size: int):
    from transformers import CLIPTextConfig

    return CLIPTextConfig(
        vocab_size=vocab_size,
        hidden_size=32,
        intermediate_size=64,
        num_hidden_layers=2,
        num_attention_heads=2,
        max_position_embeddings=77,
        projection_dim=16,
        bos_token_id=0,
        eos_token_id=1,
        pad_token_id=1,
    )


@pytest.fixture(scope="module")
def tiny_clip_dir(tmp_path_factory) -> Path:
    """A random-weight CLIPTextModelWithProjection (16-d) with its tokenizer, saved to disk."""
    from transformers import CLIPTextModelWithProjection

    path = tmp_path_factory.mktemp("tiny_clip")
    _write_tiny_clip_tokenizer(path)
    vocab_size = len(json.loads((path / "vocab.json").read_text()))
    torch.manual_seed(0)
    CLIPTextModelWithProjection(_tiny_text_config(vocab_size)).save_pretrained(path)
    return path


def _direct_clip_embeds(path: Path, texts: list[str]) -> torch.Tensor:
    """The reference: transformers called by hand, padded to the full 77 as CLIP was trained."""
    from transformers import CLIPTextModelWithProjection, CLIPTokenizer

    tok = CLIPTokenizer.from_pretrained(str(path))
    model = CLIPTextModelWithProjection.from_pretrained(str(path)).eval()
    ids = tok(texts, padding="max_length", max_length=77, truncation=True, return_tensors="pt")
    with torch.no_grad():
        return model(input_ids=ids["input_ids"]).text_embeds


class FakeEncoder(TextEncoder):
    """Deterministic pseudo-embeddings from a hash of the text: no model, instant."""

    def __init__(self, name: str = "fake", dim: int = 8) -> None:
        self.name, self.dim = name, dim

    def _encode(self, texts: list[str]) -> torch.Tensor:
        rows = [
            torch.randn(self.dim, generator=torch.Generator().manual_seed(zlib.crc32(t.encode())))
            for t in texts
        ]
        return torch.stack(rows)


class CountingEncoder(TextEncoder):
    """Wraps an encoder and records every batch it is asked to encode."""

    def __init__(self, inner: TextEncoder) -> None:
        self.inner, self.name, self.dim = inner, inner.name, inner.dim
        self.calls: list[list[str]] = []

    def _encode(self, texts: list[str]) -> torch.Tensor:
        self.calls.append(list(texts))
        return self.inner.encode(texts)


def _cos(a: torch.Tensor, b: torch.Tensor) -> float:
    return torch.nn.functional.cosine_similarity(a, b, dim=0).item()


# --------------------------------------------------------------------------- MiniLM


def test_minilm_shape_dtype_and_determinism(minilm):
    assert minilm.name == "minilm" and minilm.dim == 384
    texts = [WALK, CARTWHEEL, "", "jump"]
    a = minilm.encode(texts)
    assert a.shape == (4, 384) and a.dtype == torch.float32 and a.device.type == "cpu"
    assert torch.isfinite(a).all() and not a.requires_grad
    torch.testing.assert_close(minilm.encode(texts), a, rtol=0, atol=1e-6)
    # The bundled model ends in its own Normalize module: unit vectors, not added by us.
    torch.testing.assert_close(a.norm(dim=-1), torch.ones(4), rtol=0, atol=1e-4)


def test_minilm_paraphrase_is_closer_than_unrelated(minilm):
    walk, paraphrase, cartwheel = minilm.encode([WALK, WALK_PARAPHRASE, CARTWHEEL])
    assert _cos(walk, paraphrase) > _cos(walk, cartwheel) + 0.1


def test_null_embedding_is_empty_text(minilm):
    null = minilm.null_embedding()
    assert null.shape == (384,)
    torch.testing.assert_close(null, minilm.encode([""])[0], rtol=0, atol=1e-6)
    null.zero_()  # a caller writing into it must not change the cached one
    assert minilm.null_embedding().abs().sum() > 0


def test_encode_batch_edges(minilm):
    assert minilm.encode([]).shape == (0, 384)
    with pytest.raises(MlctError, match="not a single string"):
        minilm.encode(WALK)
    with pytest.raises(MlctError, match="takes strings"):
        minilm.encode([WALK, 3])


def test_embeddings_feed_a_trained_layer(minilm):
    """Embeddings are ordinary tensors (not inference-mode ones), so autograd accepts them."""
    c = minilm.encode([WALK, CARTWHEEL])
    assert not c.is_inference()
    layer = torch.nn.Linear(384, 4)
    layer(c).sum().backward()
    assert layer.weight.grad is not None
    assert all(not p.requires_grad for p in minilm.model.parameters())
    assert not minilm.model.training


def test_minilm_batches_internally(minilm, monkeypatch):
    """Split into batches, each row is what it was in one batch (no cross-talk via padding)."""
    texts = [WALK, CARTWHEEL, "wave"]
    whole = minilm.encode(texts)
    monkeypatch.setattr(minilm, "batch_size", 2)
    torch.testing.assert_close(minilm.encode(texts), whole, rtol=1e-4, atol=1e-5)


# --------------------------------------------------------------------------- CLIP


def test_clip_from_spec_and_bare_dir(tiny_clip_dir):
    texts = ["walk the walk", "the", "", "zzz qq"]
    expected = _direct_clip_embeds(tiny_clip_dir, texts)
    for spec in ("clip:" + str(tiny_clip_dir), str(tiny_clip_dir)):
        enc = load_text_encoder(spec)
        assert isinstance(enc, ClipTextEncoder)
        assert enc.dim == 16 and enc.name == f"clip:{tiny_clip_dir.resolve()}"
        out = enc.encode(texts)
        assert out.shape == (4, 16) and out.dtype == torch.float32 and torch.isfinite(out).all()
        # Padding to the longest caption matches padding to 77 (the causal mask hides padding).
        torch.testing.assert_close(out, expected, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(enc.null_embedding(), expected[2], rtol=1e-5, atol=1e-5)
        assert all(not p.requires_grad for p in enc.model.parameters()) and not enc.model.training
    # The name is itself a spec: a checkpoint that records it can rebuild the encoder.
    assert load_text_encoder(enc.name).name == enc.name


def test_clip_truncates_long_captions_and_batches(tiny_clip_dir):
    enc = ClipTextEncoder(tiny_clip_dir, batch_size=2)
    long = " ".join(["walk"] * 200)  # far past 77 tokens
    texts = [long, "the walk", "walk", long + " the"]
    out = enc.encode(texts)
    assert out.shape == (4, 16) and torch.isfinite(out).all()
    # Truncated to the same first 76 tokens, the two long captions embed identically.
    torch.testing.assert_close(out[0], out[3])
    torch.testing.assert_close(out, _direct_clip_embeds(tiny_clip_dir, texts), rtol=1e-5, atol=1e-5)


def test_clip_full_model_checkpoint(tmp_path):
    """A whole CLIPModel directory (how openai/clip-vit-large-patch14 ships) loads its text half."""
    from transformers import CLIPConfig, CLIPModel, CLIPVisionConfig

    _write_tiny_clip_tokenizer(tmp_path)
    vocab_size = len(json.loads((tmp_path / "vocab.json").read_text()))
    vision = CLIPVisionConfig(
        hidden_size=16, intermediate_size=32, num_hidden_layers=1, num_attention_heads=2,
        image_size=8, patch_size=4, projection_dim=16,
    )
    config = CLIPConfig(
        text_config=_tiny_text_config(vocab_size).to_dict(), vision_config=vision.to_dict(),
        projection_dim=16,
    )
    torch.manual_seed(1)
    model = CLIPModel(config).eval()
    model.save_pretrained(tmp_path)

    enc = load_text_encoder(str(tmp_path))
    assert isinstance(enc, ClipTextEncoder) and enc.dim == 16
    texts = ["walk the walk", ""]
    ids = enc.tokenizer(texts, padding="max_length", max_length=77, return_tensors="pt")
    with torch.no_grad():
        pooled = model.text_model(input_ids=ids["input_ids"]).pooler_output
        expected = model.text_projection(pooled)
    torch.testing.assert_close(enc.encode(texts), expected, rtol=1e-5, atol=1e-5)


# --------------------------------------------------------------------------- sentence-transformers


def test_sentence_transformers_dir(minilm, tmp_path):
    """A copy of the bundled MiniLM loads through sentence-transformers, as 'st:DIR', and gives
    what the lean 'minilm' loader gives (under another name: st:DIR is a path's identity)."""
    import shutil

    from mlct.text import bundled_minilm_path

    shutil.copytree(bundled_minilm_path(), tmp_path / "st")
    texts = [WALK, CARTWHEEL, ""]
    expected = minilm.encode(texts)
    for spec in ("st:" + str(tmp_path / "st"), str(tmp_path / "st")):
        enc = load_text_encoder(spec)
        assert isinstance(enc, SentenceTransformerEncoder)
        assert enc.dim == 384 and enc.name == f"st:{(tmp_path / 'st').resolve()}"
        torch.testing.assert_close(enc.encode(texts), expected, rtol=1e-5, atol=1e-6)


# --------------------------------------------------------------------------- errors


def _one_line(e: pytest.ExceptionInfo) -> str:
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_missing_directory(tmp_path):
    missing = tmp_path / "nope"
    for spec in ("clip:" + str(missing), "st:" + str(missing), str(missing)):
        with pytest.raises(MlctError) as e:
            load_text_encoder(spec)
        msg = _one_line(e)
        assert "does not exist" in msg and str(missing) in msg and "minilm" in msg


def test_directory_without_weights(tmp_path, tiny_clip_dir):
    clip = tmp_path / "clip"
    clip.mkdir()
    (clip / "config.json").write_text((tiny_clip_dir / "config.json").read_text())
    st = tmp_path / "st"
    st.mkdir()
    (st / "modules.json").write_text("[]")
    for spec in ("clip:" + str(clip), str(clip), "st:" + str(st), str(st)):
        with pytest.raises(MlctError) as e:
            load_text_encoder(spec)
        assert "no model weights" in _one_line(e)


def test_unrecognised_directory_and_wrong_kind(tmp_path, tiny_clip_dir):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(MlctError) as e:
        load_text_encoder(str(empty))
    assert "cannot tell" in _one_line(e) and "clip:DIR" in str(e.value)
    with pytest.raises(MlctError, match="no modules.json"):
        load_text_encoder("st:" + str(tiny_clip_dir))
    bert = tmp_path / "bert"
    bert.mkdir()
    (bert / "config.json").write_text(json.dumps({"model_type": "bert"}))
    with pytest.raises(MlctError, match="'bert' model, not CLIP"):
        load_text_encoder("clip:" + str(bert))
    with pytest.raises(MlctError, match="is a file"):
        load_text_encoder(str(bert / "config.json"))


def test_unknown_spec_lists_accepted_forms():
    for spec in ("bert", "clip:", "t5:/some/dir", ""):
        with pytest.raises(MlctError) as e:
            load_text_encoder(spec)
        msg = _one_line(e)
        assert "'minilm'" in msg and "clip:/path/to/dir" in msg and "st:/path/to/dir" in msg


def test_minilm_files_missing(monkeypatch, tmp_path):
    monkeypatch.setattr("mlct.shipped.MINILM_DIR", tmp_path)  # the package's copy gone
    with pytest.raises(MlctError, match="bundled MiniLM is missing .*reinstall mlct"):
        load_text_encoder("minilm")


# --------------------------------------------------------------------------- cache


def test_cache_second_call_skips_the_encoder(tmp_path):
    inner = CountingEncoder(FakeEncoder())
    enc = CachedTextEncoder(inner, EmbeddingCache(tmp_path / "c.sqlite3"))
    assert enc.name == "fake" and enc.dim == 8
    texts = ["walk", "run", "jump"]
    first = enc.encode(texts)
    assert inner.calls == [texts]
    second = enc.encode(texts)
    assert inner.calls == [texts]  # all hits: the encoder was not called again
    torch.testing.assert_close(second, first, rtol=0, atol=0)
    torch.testing.assert_close(first, FakeEncoder().encode(texts), rtol=0, atol=0)
    assert second.dtype == torch.float32 and second.shape == (3, 8)


def test_cache_shared_between_instances(tmp_path):
    path = tmp_path / "shared.sqlite3"
    a = CountingEncoder(FakeEncoder())
    CachedTextEncoder(a, path).encode(["walk", "run"])
    b = CountingEncoder(FakeEncoder())
    out = CachedTextEncoder(b, path).encode(["run", "walk"])
    assert b.calls == []
    torch.testing.assert_close(out, FakeEncoder().encode(["run", "walk"]), rtol=0, atol=0)
    # Another encoder name does not see these entries.
    c = CountingEncoder(FakeEncoder(name="other"))
    CachedTextEncoder(c, path).encode(["walk"])
    assert c.calls == [["walk"]]
    assert EmbeddingCache(path).count() == 3 and EmbeddingCache(path).count("fake") == 2


class FailingAfter(CountingEncoder):
    """Fails on its n-th batch: a run killed part way through encoding a new dataset."""

    def __init__(self, inner: TextEncoder, fail_on: int) -> None:
        super().__init__(inner)
        self.fail_on = fail_on

    def _encode(self, texts: list[str]) -> torch.Tensor:
        if len(self.calls) + 1 == self.fail_on:
            raise KeyboardInterrupt
        return super()._encode(texts)


def test_cache_encodes_many_misses_in_chunks_and_keeps_the_done_ones(tmp_path, monkeypatch):
    import mlct.text.cache as cache_module

    monkeypatch.setattr(cache_module, "ENCODE_CHUNK", 4)
    path = tmp_path / "c.sqlite3"
    texts = [f"caption {i}" for i in range(10)]
    failing = FailingAfter(FakeEncoder(), fail_on=3)
    with pytest.raises(KeyboardInterrupt):
        CachedTextEncoder(failing, path).encode(texts)
    assert [len(c) for c in failing.calls] == [4, 4]
    assert EmbeddingCache(path).count("fake") == 8  # the two finished chunks were stored
    again = CountingEncoder(FakeEncoder())
    out = CachedTextEncoder(again, path).encode(texts)
    assert again.calls == [texts[8:]]  # only what the interrupted run had not done
    torch.testing.assert_close(out, FakeEncoder().encode(texts), rtol=0, atol=0)


class RuleChangedEncoder(FakeEncoder):
    """The same name and network, a changed rule around it: a versioned cache key."""

    @property
    def cache_key(self) -> str:
        return f"{self.name}@rule2"


def test_cache_key_keeps_vectors_of_an_older_rule_out(tmp_path):
    path = tmp_path / "c.sqlite3"
    EmbeddingCache(path).put_many("fake", {"turns by a right angle": np.zeros(8, np.float32)})
    enc = CachedTextEncoder(RuleChangedEncoder(), path)
    assert enc.name == "fake"  # the identity checkpoints record is unchanged
    out = enc.encode(["turns by a right angle"])
    # the old rule's zeros are not served: the encoder's own vector is
    torch.testing.assert_close(out, FakeEncoder().encode(["turns by a right angle"]))
    assert EmbeddingCache(path).count("fake@rule2") == 1


def test_minilm_sides_cache_key_names_the_mirror_rule():
    from mlct.text.minilm import MiniLMEncoder
    from mlct.text.sides import MIRROR_VERSION
    sided, plain = object.__new__(MiniLMEncoder), object.__new__(MiniLMEncoder)
    sided.name, plain.name = "minilm+sides", "minilm"
    assert sided.cache_key == f"minilm+sides@mirror{MIRROR_VERSION}"
    assert plain.cache_key == "minilm"  # no rule around the plain network: caches stay valid


def test_cache_mixed_hits_misses_and_duplicates(tmp_path):
    inner = CountingEncoder(FakeEncoder())
    enc = CachedTextEncoder(inner, tmp_path)  # a directory holds the default file name
    assert enc.cache.path == tmp_path / CACHE_FILENAME
    enc.encode(["b", "d"])
    texts = ["a", "b", "a", "c", "d", "c", "a", ""]
    out = enc.encode(texts)
    # Only the unique misses, once each, in one call, in first-seen order.
    assert inner.calls == [["b", "d"], ["a", "c", ""]]
    torch.testing.assert_close(out, FakeEncoder().encode(texts), rtol=0, atol=0)
    torch.testing.assert_close(out[0], out[2], rtol=0, atol=0)
    assert enc.encode([]).shape == (0, 8)
    torch.testing.assert_close(enc.null_embedding(), out[-1], rtol=0, atol=0)
    assert len(inner.calls) == 2  # the null embedding came from the cache


def test_cache_with_minilm_matches_direct(minilm, tmp_path):
    enc = CachedTextEncoder(minilm, tmp_path / "m.sqlite3")
    walk, cartwheel = minilm.encode([WALK, CARTWHEEL])
    expected = torch.stack([walk, cartwheel, walk])
    torch.testing.assert_close(enc.encode([WALK, CARTWHEEL, WALK]), expected, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(enc.encode([CARTWHEEL, WALK]), expected[:2].flip(0), rtol=0, atol=0)
    assert enc.cache.count("minilm") == 2


def test_cache_dim_mismatch_names_the_file(tmp_path):
    path = tmp_path / "c.sqlite3"
    EmbeddingCache(path).put_many("fake", {"walk": np.ones(4, np.float32)})
    enc = CachedTextEncoder(FakeEncoder(dim=8), path)
    with pytest.raises(MlctError) as e:
        enc.encode(["walk"])
    msg = _one_line(e)
    assert str(path) in msg and "4-d" in msg and "8-d" in msg


def test_cache_refuses_bad_vectors_and_files(tmp_path):
    cache = EmbeddingCache(tmp_path / "c.sqlite3")
    with pytest.raises(MlctError, match="non-finite"):
        cache.put_many("fake", {"walk": np.array([1.0, np.nan], np.float32)})
    with pytest.raises(MlctError, match="1-d"):
        cache.put_many("fake", {"walk": np.ones((2, 2), np.float32)})
    assert cache.count() == 0
    # Tensors are accepted and the first write of a key wins (INSERT OR IGNORE).
    cache.put_many("fake", {"walk": torch.tensor([1.0, 2.0])})
    cache.put_many("fake", {"walk": np.array([5.0, 6.0], np.float32)})
    np.testing.assert_array_equal(cache.get_many("fake", ["walk", "run"])["walk"], [1.0, 2.0])
    assert cache.get_many("fake", ["run"]) == {}

    junk = tmp_path / "junk.sqlite3"
    junk.write_bytes(b"this is not a database" * 100)
    with pytest.raises(MlctError) as e:
        EmbeddingCache(junk)
    assert str(junk) in _one_line(e)


def test_default_cache_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path / "mlct-cache"))
    assert default_cache_dir() == tmp_path / "mlct-cache"
    assert EmbeddingCache().path == tmp_path / "mlct-cache" / CACHE_FILENAME
    new_dir = tmp_path / "new" / "dir"  # no extension: a directory to be made
    assert EmbeddingCache(new_dir).path == new_dir / CACHE_FILENAME
    assert EmbeddingCache(tmp_path / "x.db").path == tmp_path / "x.db"
    monkeypatch.delenv("MLCT_CACHE")
    assert default_cache_dir() == Path.home() / ".cache" / "mlct"


def _vec(key: str) -> np.ndarray:
    return np.full(3, zlib.crc32(key.encode()) % 97, np.float32)


def _hammer(path: str, rank: int) -> None:
    """One 'DDP rank': many small overlapping writes and reads against the shared file."""
    cache = EmbeddingCache(path)
    for i in range(60):
        keys = [f"t{(i + k) % 60}" for k in range(rank, rank + 5)]
        cache.put_many("fake", {k: _vec(k) for k in keys})
        got = cache.get_many("fake", keys, dim=3)
        assert set(got) == set(keys)


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_cache_concurrent_processes(tmp_path):
    path = str(tmp_path / "c.sqlite3")
    EmbeddingCache(path)
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_hammer, args=(path, r)) for r in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0, 0, 0]
    cache = EmbeddingCache(path)
    got = cache.get_many("fake", [f"t{i}" for i in range(60)], dim=3)
    assert len(got) == 60 == cache.count()
    for k, v in got.items():
        np.testing.assert_array_equal(v, _vec(k))


def test_minilm_tokens_carries_pooled_vector_and_token_states(minilm):
    from mlct.text.encoders import TOKEN_SLOTS, token_slots_of

    tokens = load_text_encoder("minilm+tokens")
    assert tokens.name == "minilm+tokens" and tokens.dim == (1 + TOKEN_SLOTS) * 384
    assert token_slots_of("minilm+tokens") == TOKEN_SLOTS and token_slots_of("minilm") == 0
    left, right, jump = "a person waves the left hand", "a person waves the right hand", "jumps"
    both = tokens.encode([left, jump]).view(2, 1 + TOKEN_SLOTS, 384)
    torch.testing.assert_close(both[:, 0], minilm.encode([left, jump]), rtol=0, atol=1e-5)
    # [CLS] a person waves the left hand [SEP]: 8 rows, then zeros; the batch's padding is not kept
    assert (both[0, 1:].abs().sum(-1) > 0).sum() == 8 and (both[1, 1:].abs().sum(-1) > 0).sum() == 3
    torch.testing.assert_close(tokens.encode([jump])[0], both[1].flatten(), rtol=0, atol=1e-5)
    # the side lives in one token row, far more than in the pooled vector
    a, b = tokens.encode([left, right]).view(2, 1 + TOKEN_SLOTS, 384)
    cos = torch.nn.functional.cosine_similarity(a, b, dim=-1)
    assert cos[0] > 0.95 and cos[1 + 5] < 0.9  # pooled vs the "left"/"right" token
