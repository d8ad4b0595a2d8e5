"""The cuda-graphs backend (generate/backends/cuda_graphs.py) against the torch backend.

On the CPU the backend's own code runs without graphs (the noise handed to the graph as an
input, the padded batch and length buckets, the de-normalisation on the device): it must give
the torch backend's motions for the same seeds. On a GPU, when there is one, the same checks
run through captured graphs (CI has none; bench/gpu/check.sh runs them on a lent one).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

import mlct
from mlct.errors import MlctError
from mlct.generate.bundle import read_bundle
from mlct.generate.backends.cuda_graphs import QueuedNoise
from mlct.generate.load import cuda_graph_generator, load_torch
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.bundle import bundled_model_dir
from mlct.cuda_graphs import GraphCache

from bundle_factory import random_bundle

pytestmark = pytest.mark.usefixtures("one_thread")

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
JOINTS_M = 1e-3  # the most a joint may move between the backends, in metres
TEXTS = ["a person walks forward", "a person jumps up high", "someone waves with the left hand"]


@pytest.fixture(scope="module", params=DEVICES)
def pair(request) -> tuple[MotionGenerator, MotionGenerator]:
    folder = bundled_model_dir()
    return (load_torch(folder, request.param),
            cuda_graph_generator(*read_bundle(folder), request.param))


def largest_gap(a, b) -> float:
    assert [m.joints.shape for m in a] == [m.joints.shape for m in b]
    return max(float(np.abs(x.joints - y.joints).max()) for x, y in zip(a, b))


@pytest.mark.parametrize("nfe", [1, 5])
def test_same_seeds_same_motions_across_buckets(pair, nfe) -> None:
    """Batch 3 (padded to 4), mixed lengths (decoded at a 32-frame bucket), per-item seeds."""
    eager, graphed = pair
    for lengths, seed in (([60, 196, 17], 7), ([100], [3])):
        texts = TEXTS[: len(lengths)]
        a = eager.generate(texts, lengths=lengths, nfe=nfe, seed=seed, candidates=1,
                           split_actions=False)
        b = graphed.generate(texts, lengths=lengths, nfe=nfe, seed=seed, candidates=1,
                             split_actions=False)
        assert largest_gap(a, b) < JOINTS_M
        assert [m.joints.shape[0] for m in b] == lengths


def test_best_of_n_and_one_generator_for_the_batch(pair) -> None:
    """The critic's path (sample_latents, then decode: two graphs) and an int seed."""
    eager, graphed = pair
    a = eager.generate(TEXTS[:2], seconds=3, seed=11, candidates=4, split_actions=False)
    b = graphed.generate(TEXTS[:2], seconds=3, seed=11, candidates=4, split_actions=False)
    assert largest_gap(a, b) < JOINTS_M


def test_text_network_padded_to_its_buckets(pair) -> None:
    eager, graphed = pair
    texts = ["a person walks forward and then turns left to wave with the right hand", "jumps"]
    a = eager.text_encoder.encode(texts)
    b = graphed.text_encoder.encode(texts)
    assert graphed.text_encoder._graphs is not None
    assert float((a.cpu() - b.cpu()).abs().max()) < 1e-4


def test_ddim_and_transformer_decoder(tmp_path) -> None:
    """Two passes per step (classifier-free guidance, the null text an input), no fresh noise
    after x_T, and a decoder that masks padded frames."""
    folder = random_bundle(tmp_path / "tiny", "ddim", "minilm")
    for device in DEVICES:
        eager = load_torch(folder, device)
        graphed = cuda_graph_generator(*read_bundle(folder), device)
        a = eager.generate(TEXTS[:2], lengths=[64, 9], nfe=3, seed=1, split_actions=False)
        b = graphed.generate(TEXTS[:2], lengths=[64, 9], nfe=3, seed=1, split_actions=False)
        assert largest_gap(a, b) < JOINTS_M


def test_noise_that_was_not_drawn_is_refused() -> None:
    queue = QueuedNoise(torch.zeros(1, 2, 3, 4))
    assert queue.randn((2, 3, 4)).shape == (2, 3, 4)
    with pytest.raises(ValueError, match="not drawn"):
        queue.randn((2, 3, 4))


def test_the_backend_needs_a_cuda_device() -> None:
    if torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    with pytest.raises(MlctError, match="needs a CUDA device"):
        mlct.load(backend="cuda-graphs")
    with pytest.raises(MlctError, match="CUDA is not available"):
        mlct.load(device="cuda")


def test_read_copies_the_outputs_out() -> None:
    """`read` gets the function's outputs (on a GPU the graph's buffers, under the cache's
    lock); without one the outputs come back as they are."""
    graphs = GraphCache(lambda key, x: x * key)
    x = torch.arange(3.0)
    assert torch.equal(graphs(2, x), x * 2)
    assert graphs(2, x, read=lambda out: out.sum().item()) == 6.0


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a GPU")
def test_a_bucket_is_captured_once_and_kept_least_recently_used() -> None:
    calls = []

    def double(key, x):
        calls.append(key)
        return x * 2

    graphs = GraphCache(double, max_graphs=2, warmup=1)
    x = torch.arange(4.0, device="cuda")
    assert torch.equal(graphs("a", x), x * 2)
    assert torch.equal(graphs("a", x + 1), (x + 1) * 2)  # replayed on new input values
    assert graphs.captures == 1
    graphs("b", x)
    graphs("c", x)  # evicts "a"
    graphs("a", x)
    assert graphs.captures == 4


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a GPU")
def test_auto_picks_cuda_graphs_on_a_gpu(monkeypatch) -> None:
    monkeypatch.delenv("MLCT_BACKEND", raising=False)  # conftest pins the torch backend
    generator = mlct.load(device="cuda")
    assert generator.backend == "cuda-graphs"
    motion = generator.generate("a person jumps", seconds=2, seed=0)[0]
    assert np.isfinite(motion.joints).all()


def test_time_terms_taken_in_order_match_the_lookup() -> None:
    """On a GPU the condition cache hands out each step's time terms in the sampler's order
    instead of looking them up by t (a read of the device): the same terms, so the same F."""
    from mlct.nn.denoiser import ConditionCache

    gen = load_torch(bundled_model_dir())
    cond = gen.encode_text(["a person walks forward"])
    times = gen.sampler.times(5)
    looked_up = gen.denoiser.condition_terms(cond, times)
    ordered = ConditionCache(cond, looked_up.text, {}, [looked_up.times[v] for v in times.tolist()])
    x = torch.randn(1, *gen.ae.latent_shape, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        for t in times:
            plain = gen.denoiser(x, t.expand(1), cond)
            assert torch.allclose(gen.denoiser(x, t.expand(1), cond, cache=ordered), plain,
                                  atol=1e-5)
    assert not ordered.in_order  # one taken per call


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a GPU")
def test_the_gpu_gives_the_cpus_motions() -> None:
    """Eager on both devices, float32: the seeds' noise is drawn on the host and the time terms
    come in order on the GPU, so the motions agree."""
    kwargs = dict(lengths=[120, 60], nfe=5, seed=[4, 5], candidates=1, split_actions=False)
    a = load_torch(bundled_model_dir(), "cpu").generate(TEXTS[:2], **kwargs)
    b = load_torch(bundled_model_dir(), "cuda").generate(TEXTS[:2], **kwargs)
    assert largest_gap(a, b) < 5 * JOINTS_M
