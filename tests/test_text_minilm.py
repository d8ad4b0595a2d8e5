"""The lean bundled-MiniLM loader (text/minilm.py, text/bert.py): sentence-transformers' embeddings
without importing it, so that `mlct generate` starts in a couple of seconds."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from mlct.errors import MlctError
from mlct.text import bundled_minilm_path
from mlct.text.bert import BertConfig
from mlct.text.encoders import TOKEN_SLOTS, load_text_encoder
from mlct.text.minilm import MiniLMEncoder, check_pipeline

pytest.importorskip("tokenizers")

pytestmark = pytest.mark.usefixtures("one_thread")

# Cased, padded, punctuated, accented, CJK, empty, and longer than max_seq_length (256 tokens,
# so truncated); together in one batch they also pad each other.
TEXTS = [
    "a person walks forward",
    "",
    "  A MAN does a Cartwheel!  ",
    "café naïve résumé 北京",
    "jump",
    "a person waves the left hand, then sits down slowly on a chair",
    "step " * 300,
]
PARITY = 1e-5  # max abs difference allowed against sentence-transformers


@pytest.fixture(scope="module")
def lean() -> MiniLMEncoder:
    enc = load_text_encoder("minilm")
    assert isinstance(enc, MiniLMEncoder)
    return enc


@pytest.fixture(scope="module")
def lean_tokens() -> MiniLMEncoder:
    enc = load_text_encoder("minilm+tokens")
    assert isinstance(enc, MiniLMEncoder)
    return enc


def _reference(token_slots: int):  # the sentence-transformers path on the same files
    pytest.importorskip("sentence_transformers")
    from mlct.text.encoders import SentenceTransformerEncoder

    return SentenceTransformerEncoder(bundled_minilm_path(), name="reference",
                                      token_slots=token_slots)


def test_names_and_sizes_are_those_of_the_sentence_transformers_path(lean, lean_tokens):
    """Same names, same sizes: embedding caches and trained models keep working."""
    assert (lean.name, lean.dim) == ("minilm", 384)
    assert (lean_tokens.name, lean_tokens.dim) == ("minilm+tokens", (1 + TOKEN_SLOTS) * 384)
    assert load_text_encoder(" MiniLM ").name == "minilm"


@pytest.mark.slow
def test_pooled_embeddings_match_sentence_transformers(lean):
    reference = _reference(0)
    ours, theirs = lean.encode(TEXTS), reference.encode(TEXTS)
    assert (ours - theirs).abs().max() < PARITY
    for text in TEXTS[:3]:  # alone: no batch padding on either side
        assert (lean.encode([text]) - reference.encode([text])).abs().max() < PARITY


@pytest.mark.slow
def test_token_states_match_sentence_transformers(lean_tokens):
    reference = _reference(TOKEN_SLOTS)
    ours, theirs = lean_tokens.encode(TEXTS), reference.encode(TEXTS)
    assert (ours - theirs).abs().max() < PARITY
    rows = ours.view(len(TEXTS), 1 + TOKEN_SLOTS, 384).abs().sum(-1) > 0
    # [CLS] a person walks forward [SEP]: 6 token rows after the pooled one, the rest zero.
    assert rows[0].tolist() == [True] * 7 + [False] * (TOKEN_SLOTS - 6)
    assert rows[-1].all()  # the long caption fills every slot


def test_batches_and_padding_do_not_change_a_row(lean_tokens, monkeypatch):
    whole = lean_tokens.encode(TEXTS)
    monkeypatch.setattr(lean_tokens, "batch_size", 2)
    torch.testing.assert_close(lean_tokens.encode(TEXTS), whole, rtol=0, atol=1e-5)
    torch.testing.assert_close(lean_tokens.encode(TEXTS[:1])[0], whole[0], rtol=0, atol=1e-5)


def test_unit_vectors_ordinary_tensors_frozen_model(lean):
    out = lean.encode(TEXTS)
    assert out.dtype == torch.float32 and not out.is_inference() and not out.requires_grad
    torch.testing.assert_close(out.norm(dim=-1), torch.ones(len(TEXTS)), rtol=0, atol=1e-5)
    assert not lean.model.training
    assert all(not p.requires_grad for p in lean.model.parameters())


@pytest.mark.slow
def test_loading_the_bundled_minilm_imports_no_hugging_face_library():
    """The point of the lean loader: none of the seconds-long imports on the way to an embedding."""
    code = ("import sys; from mlct.text import load_text_encoder; "
            "load_text_encoder('minilm+tokens').encode(['a person walks']); "
            "heavy = ('sentence_transformers', 'transformers', 'sklearn'); "
            "print(sorted(m for m in heavy if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=_child_env(), check=True).stdout
    assert out.strip() == "[]"


def _child_env() -> dict[str, str]:
    src = str(Path(__file__).resolve().parent.parent / "src")
    path = os.pathsep.join(p for p in (src, os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1"}


# --------------------------------------------------------------------------- what it refuses


def _copy(tmp_path: Path) -> Path:
    model = tmp_path / "minilm"
    shutil.copytree(bundled_minilm_path(), model)
    return model


def test_pipelines_other_than_mean_pooling_and_normalize_are_refused(tmp_path):
    model = _copy(tmp_path)
    assert check_pipeline(model) == 256
    pooling = model / "1_Pooling" / "config.json"
    config = json.loads(pooling.read_text())
    pooling.write_text(json.dumps({**config, "pooling_mode_mean_tokens": False,
                                   "pooling_mode_cls_token": True}))
    with pytest.raises(ValueError, match="pooling_mode_mean_tokens"):
        check_pipeline(model)
    pooling.write_text(json.dumps(config))
    modules = json.loads((model / "modules.json").read_text())
    (model / "modules.json").write_text(json.dumps(modules[:2]))  # no Normalize
    with pytest.raises(ValueError, match="not"):
        check_pipeline(model)


def test_unsupported_configs_are_refused():
    config = json.loads((bundled_minilm_path() / "config.json").read_text())
    assert BertConfig.from_dict(config).num_hidden_layers == 6
    for key, value in [("model_type", "roberta"), ("hidden_act", "relu"),
                       ("position_embedding_type", "relative_key")]:
        with pytest.raises(ValueError, match=key):
            BertConfig.from_dict({**config, key: value})
    with pytest.raises(ValueError, match="hidden_size"):
        BertConfig.from_dict({k: v for k, v in config.items() if k != "hidden_size"})


def test_damaged_files_give_one_line_errors(tmp_path):
    model = _copy(tmp_path)
    weights = (model / "model.safetensors").read_bytes()
    (model / "model.safetensors").write_bytes(weights[:5000])
    with pytest.raises(MlctError, match="cannot load the MiniLM") as e:
        MiniLMEncoder(model, name="x")
    assert "\n" not in str(e.value)
    (model / "model.safetensors").write_bytes(weights)
    (model / "tokenizer.json").write_text("{bad json")
    with pytest.raises(MlctError, match="cannot load the MiniLM"):
        MiniLMEncoder(model, name="x")
