"""The generator's layers (docs/architecture.md, "generate"): the prompt composer makes every
sample through the core, one call per batch, whichever backend's networks the core holds."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from mlct.generate.backends.pytorch import TorchNetworks
from mlct.generate.bundle import bundled_model_dir, read_bundle
from mlct.generate.compose.actions import plain_subject
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.core import MotionCore
from mlct.generate.seeds import Sampling


class CountingNetworks(TorchNetworks):
    """The torch networks, counting the core's calls and the rows of each."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.calls: Counter[str] = Counter()
        self.rows: list[tuple[str, int]] = []

    def latents(self, cond, *args):
        self.calls["latents"] += 1
        self.rows.append(("latents", len(cond)))
        return super().latents(cond, *args)

    def decode(self, z, lengths):
        self.calls["decode"] += 1
        return super().decode(z, lengths)

    def features(self, cond, *args):
        self.calls["features"] += 1
        self.rows.append(("features", len(cond)))
        return self.decode(TorchNetworks.latents(self, cond, *args[:4]), args[4])


@pytest.fixture(scope="module")
def bundle():
    return read_bundle(bundled_model_dir())


def test_the_onnx_backends_bundle_reads_each_tensor_when_first_asked_for() -> None:
    """read_bundle(numpy=True): the file's tensors, float16 ones as float32, read one by one."""
    from safetensors.numpy import load_file

    _, lazy = read_bundle(bundled_model_dir(), numpy=True)
    assert np.array_equal(lazy["norm.std"], lazy["norm.std"]) and len(lazy._read) == 1
    whole = load_file(str(bundled_model_dir() / "model.safetensors"))
    assert sorted(lazy) == sorted(whole) and len(lazy) == len(whole)
    for key, value in whole.items():
        expected = value.astype(np.float32) if value.dtype == np.float16 else value
        assert lazy[key].dtype == expected.dtype and np.array_equal(lazy[key], expected), key
    with pytest.raises(KeyError):
        lazy["no.such.tensor"]


def counting(bundle) -> tuple[MotionGenerator, CountingNetworks]:
    networks = CountingNetworks(*bundle)
    return MotionGenerator(MotionCore(networks, plain_subject)), networks


def test_plain_prompts_are_one_call_of_the_core(bundle) -> None:
    gen, nets = counting(bundle)
    made = gen.generate(["a person jumps", "a person waves", "a person kicks"], seconds=3,
                        seed=0, candidates=1)
    assert nets.calls == {"features": 1, "decode": 1} and nets.rows == [("features", 3)]
    assert [m.joints.shape[0] for m in made] == [60, 60, 60]


def test_best_of_n_is_one_batch_of_latents_and_one_of_decoding(bundle) -> None:
    gen, nets = counting(bundle)
    assert gen.critic is not None  # the bundled model's
    gen.generate(["a person jumps", "a person waves"], seconds=3, seed=0, candidates=4)
    assert nets.calls == {"latents": 1, "decode": 1} and nets.rows == [("latents", 8)]


def test_a_mixed_list_is_one_batch_whatever_its_prompts_become(bundle) -> None:
    """A sequence, a body with its arms and a plain prompt: five samples, one call."""
    gen, nets = counting(bundle)
    texts = ["a person walks forward, then sits down", "a person walks while waving",
             "a person jumps"]
    made = gen.generate(texts, seconds=[6, 4, 3], seed=1, candidates=1)
    assert nets.calls["features"] == 1 and nets.rows == [("features", 5)]
    alone = [counting(bundle)[0].generate(t, seconds=n, seed=1 + i, candidates=1)[0]
             for i, (t, n) in enumerate(zip(texts, [6, 4, 3]))]
    for a, b in zip(made, alone):  # the batch changes nothing but float rounding
        np.testing.assert_allclose(a.joints, b.joints, atol=1e-4)


def test_the_core_alone_gives_features_and_joints(bundle) -> None:
    """text -> latents -> features -> joints, without the composer: the core's own calls."""
    core = MotionCore(TorchNetworks(*bundle))
    cond = core.encode_text(["a person walks forward"])
    feats = core.features(cond, [3], [50], Sampling(core.check_nfe(None)))
    direct = core.decode(core.sample_latents(cond, None, [3]), [50])
    np.testing.assert_array_equal(feats[0], direct[0])
    assert core.joints(feats[0]).shape == (50, core.skeleton.n_joints, 3)
