"""The onnx backend's low-overhead sampling (generate/backends/onnx/sampler.py): the host-side step loop
and the one-call sampler graph give the torch backend's motions for the same seeds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import mlct
from mlct.generate.backends.onnx.convert import convert_to_onnx
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.load import load_onnx
from mlct.generate.bundle import bundled_model_dir

pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

pytestmark = pytest.mark.usefixtures("one_thread")

JOINTS_M = 1e-3  # the same seed gives the same motion within 1 mm
TEXTS = ["a person walks forward", "a person jumps up high", "someone waves with the left hand"]
LENGTHS = [196, 60, 13]


@pytest.fixture(scope="module")
def backends(tmp_path_factory) -> tuple[MotionGenerator, MotionGenerator]:
    folder = convert_to_onnx(bundled_model_dir(), tmp_path_factory.mktemp("onnx") / "model",
                             read_only=True)
    pair = mlct.load(folder), mlct.load(folder, backend="onnx")
    for generator in pair:
        # a 196-frame walk would be remade as chained takes (generate/compose/keep_going.py), whose
        # own generate() calls build the sampler graph before the test means to
        generator.keep_going = False
    return pair


def gap(a, b) -> float:
    assert [m.joints.shape for m in a] == [m.joints.shape for m in b]
    return max(float(np.abs(x.joints - y.joints).max()) for x, y in zip(a, b))


@pytest.mark.parametrize("nfe", [1, 5, 10])
def test_the_sampler_graph_gives_the_torch_motions(backends, nfe) -> None:
    torch_gen, onnx_gen = backends
    # one sample a prompt: best-of-N samples the latents, then decodes only the chosen ones
    want = torch_gen.generate(TEXTS, lengths=LENGTHS, nfe=nfe, seed=3, candidates=1)
    first = onnx_gen.generate(TEXTS, lengths=LENGTHS, nfe=nfe, seed=3, candidates=1)  # loop
    assert onnx_gen.networks.graph_sessions.fused.get(nfe) is None  # a first call does not build the graph
    second = onnx_gen.generate(TEXTS, lengths=LENGTHS, nfe=nfe, seed=3, candidates=1)
    assert onnx_gen.networks.graph_sessions.fused.get(nfe) is not None
    assert gap(want, first) < JOINTS_M and gap(want, second) < JOINTS_M
    for x, y in zip(want, second):
        np.testing.assert_allclose(y.features, x.features, atol=1e-3)
    other = onnx_gen.generate(TEXTS[:1], lengths=[60], nfe=nfe, seed=4, candidates=1)
    assert np.abs(other[0].joints - second[0].joints[:60]).max() > 0.01  # the seed matters


def test_sample_latents_matches_torch_for_every_seed_form(backends) -> None:
    torch_gen, onnx_gen = backends
    cond = torch_gen.encode_text(TEXTS)
    for seed in (5, [5, 6, 7]):  # one generator for the batch, one per item
        want = torch_gen.sample_latents(cond, 3, seed)
        got = onnx_gen.sample_latents(cond, 3, seed)
        torch.testing.assert_close(got, want, rtol=0, atol=1e-4)
    a, b = onnx_gen.sample_latents(cond, 3, None), onnx_gen.sample_latents(cond, 3, None)
    assert not torch.equal(a, b)  # no seed: random


def test_without_the_onnx_package_the_step_loop_is_used(backends, monkeypatch) -> None:
    import sys

    torch_gen, _ = backends
    onnx_gen = mlct.load(Path(backends[1].networks.graphs.denoiser).parent.parent, backend="onnx")
    monkeypatch.setitem(sys.modules, "onnx", None)  # `import onnx` raises ImportError
    want = torch_gen.generate(TEXTS[:1], lengths=[80], nfe=2, seed=1, candidates=1)
    for _ in range(3):
        got = onnx_gen.generate(TEXTS[:1], lengths=[80], nfe=2, seed=1, candidates=1)
        assert gap(want, got) < JOINTS_M
    assert onnx_gen.networks.graph_sessions.fused == {2: None}


def test_at_most_a_few_sampler_graphs_are_built(backends) -> None:
    from mlct.generate.backends.onnx.networks import MAX_SAMPLER_GRAPHS

    torch_gen, _ = backends
    onnx_gen = mlct.load(Path(backends[1].networks.graphs.denoiser).parent.parent, backend="onnx")
    for nfe in range(1, MAX_SAMPLER_GRAPHS + 3):
        for _ in range(2):
            got = onnx_gen.generate(TEXTS[:1], lengths=[40], nfe=nfe, seed=0, candidates=1)
    assert sorted(onnx_gen.networks.graph_sessions.fused) == list(range(1, MAX_SAMPLER_GRAPHS + 1))
    want = torch_gen.generate(TEXTS[:1], lengths=[40], nfe=MAX_SAMPLER_GRAPHS + 2, seed=0,
                              candidates=1)
    assert gap(want, got) < JOINTS_M  # the step loop beyond them


def test_batch_one_runs_on_one_thread_and_larger_batches_on_all(backends) -> None:

    torch_gen, _ = backends
    onnx_gen = load_onnx(Path(backends[1].networks.graphs.denoiser).parent.parent,
                                        threads=2)
    # as the fixture's pair: the walk of 196 frames may otherwise be remade as chained takes
    # (generate/compose/keep_going.py) on this side only (it was, with the weights of 2026-11-27)
    onnx_gen.keep_going = False
    onnx_gen.networks.spinning = False  # as on a machine of fewer than 4 cores (below: 4 or more)
    for texts, lengths in ((TEXTS[:1], [50]), (TEXTS, LENGTHS)):
        want = torch_gen.generate(texts, lengths=lengths, nfe=2, seed=7, candidates=1)
        for _ in range(2):
            got = onnx_gen.generate(texts, lengths=lengths, nfe=2, seed=7, candidates=1)
        assert gap(want, got) < JOINTS_M
    threads = {key: s.get_session_options().intra_op_num_threads
               for key, s in onnx_gen.networks.graph_sessions.sessions.items()}
    # a session per thread count; batch 1's with its batch dimension fixed and its steps
    # apart from the decoder, which runs in its own session on both threads
    assert threads == {(2, 1, True, True, False): 1, (2, 2, False, False, False): 2}
    assert onnx_gen.ae.session.get_session_options().intra_op_num_threads == 2
    fixed = onnx_gen.networks.graph_sessions.sessions[(2, 1, True, True, False)]
    assert [i.shape[0] for i in fixed.get_inputs() if i.name in ("x", "text")] == [1] * 2
    assert [o.name for o in fixed.get_outputs()] == ["latent"]
    # the step times and coefficients are the graph's constants, not inputs
    assert not {"times", "coef", "valid"} & {i.name for i in fixed.get_inputs()}


def test_spinning_steps_run_on_two_threads_that_stop_with_the_run(backends, monkeypatch
                                                                   ) -> None:
    """While two logical CPUs are idle for them (onnx_io.spin_now: other processes' load, or
    the machine's size where it says none) batch 1's steps run on two threads spinning within
    the run only, otherwise on one; the choice is made at every call, the motion is the same."""
    import mlct.generate.backends.onnx.networks as onnx_backend
    import mlct.onnx_io as onnx_io

    torch_gen, _ = backends
    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    gen = load_onnx(folder, threads=2)
    gen.keep_going = False
    made = {}
    # others' load in logical CPUs (None: the machine does not say), the machine's CPUs
    for others, cores in ((None, 2), (0.05, 2), (1.0, 2), (None, 8), (6.5, 8)):
        monkeypatch.setattr(onnx_io.os, "cpu_count", lambda cores=cores: cores)
        monkeypatch.setattr(onnx_io, "OTHER_LOAD", lambda others=others: others)
        for _ in range(2):  # the first call of all builds the graph at its second call
            made[others, cores] = gen.generate(TEXTS[:1], lengths=[50], nfe=2, seed=7,
                                               candidates=1)
        spinning = cores >= 4 if others is None else cores - others >= 1.75
        key = (2, 2 if spinning else 1, True, True, spinning)  # steps, threads, batch 1, apart,
        # spinning
        options = gen.networks.graph_sessions.sessions[key].get_session_options()
        assert options.intra_op_num_threads == key[1]
        assert options.get_session_config_entry("session.intra_op.allow_spinning") == (
            "1" if spinning else "0")
        if spinning:
            assert options.get_session_config_entry("session.force_spinning_stop") == "1"
    assert len(gen.networks.graph_sessions.sessions) == 2  # one of each kind, kept
    for motion in made.values():
        assert gap(made[None, 2], motion) < 1e-4
    want = torch_gen.generate(TEXTS[:1], lengths=[50], nfe=2, seed=7, candidates=1)
    assert gap(want, made[0.05, 2]) < JOINTS_M


def test_decoding_apart_gives_the_one_graph_features(backends) -> None:
    """Batch 1's steps in a graph of their own and the decoder in its session: the same
    arithmetic as the sampler graph that holds both, which one thread runs."""

    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    features = []
    for threads in (2, 1):  # batch 1's steps apart on two threads, the one graph on one
        gen = load_onnx(folder, threads=threads)
        cond = gen.encode_text(TEXTS[:1])
        for _ in range(2):  # the second call builds the graph
            got = gen.sample_features(cond, 3, [4], None, [70])
        assert [key[3] for key in gen.networks.graph_sessions.sessions] == [threads == 2]
        features.append(got[0])
    assert features[0].shape == (70, features[1].shape[1])
    np.testing.assert_allclose(features[0], features[1], rtol=0, atol=1e-5)


def test_a_large_graph_keeps_all_threads_at_batch_one(backends, monkeypatch) -> None:
    """A sampler graph too big for one thread (paper size) runs batch 1 on all threads, which
    spin within the run while the machine is idle (onnx_io.spin_now, asked at every call; a
    session of each kind, made when first needed), the same motion either way."""
    import mlct.generate.backends.onnx.networks as onnx_backend
    import mlct.onnx_io as onnx_io

    monkeypatch.setattr(onnx_backend, "ONE_THREAD_MAX_BYTES", 1000)  # every graph is "large"
    onnx_gen = load_onnx(
        Path(backends[1].networks.graphs.denoiser).parent.parent, threads=2)
    onnx_gen.keep_going = False
    monkeypatch.setattr(onnx_io.os, "cpu_count", lambda: 2)
    made, kinds = [], []
    for others in (0.05, 0.05, 1.0, 0.05):  # the first call runs the step loop
        monkeypatch.setattr(onnx_io, "OTHER_LOAD", lambda others=others: others)
        made.append(onnx_gen.generate(TEXTS[:1], lengths=[50], nfe=2, seed=7, candidates=1))
        kinds.append(sorted(key[4] for key in onnx_gen.networks.graph_sessions.sessions))
    assert kinds == [[], [True], [False, True], [False, True]]
    for key, session in onnx_gen.networks.graph_sessions.sessions.items():
        options = session.get_session_options()
        assert options.intra_op_num_threads == 2
        assert options.get_session_config_entry("session.intra_op.allow_spinning") == (
            "1" if key[4] else "0")
    for motion in made[1:]:
        assert gap(made[0], motion) < 1e-4


def test_keep_going_gives_the_torch_motions(backends) -> None:
    """A jog asked for 8 s is made as chained takes on both backends: the takes' sampling
    agrees to float rounding, and so do the seams chosen from them."""
    torch_gen, onnx_gen = backends
    made = []
    for generator in backends:
        generator.keep_going = True
        try:
            made.append(generator.generate("a person jogs forward", seconds=8.0, seed=0))
        finally:
            generator.keep_going = False
    assert gap(*made) < JOINTS_M
    two = 40  # the last 2 s still jog: the takes were chained, not one stopping sample
    root = made[1][0].joints[-two:, 0, [0, 2]]
    assert np.linalg.norm(np.diff(root, axis=0), axis=1).sum() > 2.0


def test_a_large_batch_is_run_by_the_torch_networks_with_the_same_motions(backends) -> None:
    from mlct.generate.backends.onnx.networks import TORCH_MIN_BATCH

    assert TORCH_MIN_BATCH is not None and TORCH_MIN_BATCH > 1
    torch_gen, _ = backends
    onnx_gen = load_onnx(Path(backends[1].networks.graphs.denoiser).parent.parent)
    onnx_gen.keep_going = False
    texts = (TEXTS * TORCH_MIN_BATCH)[:TORCH_MIN_BATCH]
    lengths = [40 + 3 * i for i in range(TORCH_MIN_BATCH)]
    small = onnx_gen.generate(texts[:-1], lengths=lengths[:-1], nfe=3, seed=2, candidates=1)
    assert onnx_gen.networks._torch is None  # one short of the size: the ONNX graphs
    want = torch_gen.generate(texts, lengths=lengths, nfe=3, seed=2, candidates=1)
    got = onnx_gen.generate(texts, lengths=lengths, nfe=3, seed=2, candidates=1)
    assert onnx_gen.networks._torch is not None
    assert gap(want, got) < JOINTS_M
    assert gap(small, got[:-1]) < JOINTS_M  # per-item seeds: the batch size changes nothing


def test_the_fused_attention_computes_what_the_exported_one_does(backends) -> None:
    """onnx_attention.fuse_attention: every denoiser block's attention becomes one
    com.microsoft Attention node in the sampler graph, with the step loop's latents; a block whose
    attention reads a mask is not that pattern and is left as it is."""
    import onnx
    from onnx import TensorProto, helper

    from mlct.generate.backends.onnx.attention import fuse_attention

    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    gen = load_onnx(folder, threads=2)  # the steps apart, on one thread
    gen.networks.spinning = False
    cond = torch.as_tensor(gen.encode_text(TEXTS[:1]))  # (numpy on this backend)
    for _ in range(2):  # the second call builds the graph
        gen.sample_features(cond, 3, [5], None, [40])
    nets = gen.networks
    graph = onnx.ModelProto.FromString(nets.graph_sessions.steps_only[3]).graph
    layers = gen.config.denoiser.layers
    assert sum(node.op_type == "Attention" for node in graph.node) == 3 * layers  # every block
    session, apart = nets.graph_sessions.sampler(3, 1)
    feeds = nets._feeds(cond, 3, [5])
    feeds["text"] = cond.numpy()
    (latent,) = session.run(["latent"], {k: feeds[k] for k in ("x", "noise", "text")})
    # the step loop runs the exported graph, its attentions unfused
    np.testing.assert_allclose(latent, nets._latents(None, cond, 3, [5]), rtol=0,
                               atol=1e-5)
    assert np.abs(latent).max() > 0.1

    model = onnx.load(str(gen.networks.graphs.denoiser))
    softmax = next(node for node in model.graph.node if node.op_type == "Softmax")
    model.graph.input.append(helper.make_tensor_value_info("mask", TensorProto.BOOL, None))
    model.graph.initializer.append(helper.make_tensor("minus", TensorProto.FLOAT, [], [-1e4]))
    where = helper.make_node("Where", ["mask", softmax.input[0], "minus"], ["masked"])
    model.graph.node.insert(list(model.graph.node).index(softmax), where)
    softmax.input[0] = "masked"
    assert fuse_attention(model, gen.config.denoiser.heads) == layers - 1
    kinds = [node.op_type for node in model.graph.node]
    assert kinds.count("Attention") == layers - 1 and kinds.count("Softmax") == 1


def test_candidates_sample_through_the_steps_graph_and_decode_through_the_halves(backends
                                                                                ) -> None:
    """generate()'s best of N: from the second call with a step count the N latents come from
    the steps' graph (SamplerGraphs.steps) and a single latent is decoded by the
    decoder's halves, with the step loop's and the whole decoder's numbers."""

    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    gen = load_onnx(folder, threads=2)
    gen.networks.spinning = False
    rows = torch.as_tensor(gen.encode_text(TEXTS[:1])).repeat_interleave(4, dim=0)
    loop = gen.sample_latents(rows, 3, [1, 2, 3, 4])  # the first call: the step loop
    assert not gen.networks.graph_sessions.steps_only
    graph = gen.sample_latents(rows, 3, [1, 2, 3, 4])
    assert 3 in gen.networks.graph_sessions.steps_only and any(key[:4] == (3, 2, False, True) for key in gen.networks.graph_sessions.sessions)
    np.testing.assert_allclose(graph.numpy(), loop.numpy(), rtol=0, atol=1e-5)
    one = gen.sample_latents(rows[:1], 3, [7])  # batch 1: the one-thread steps session
    assert (3, 1, True, True, False) in gen.networks.graph_sessions.sessions
    np.testing.assert_allclose(one.numpy(), gen.networks._latents(None, rows[:1], 3, [7]),
                               rtol=0, atol=1e-5)  # the same latent by the step loop
    whole = gen.decode(one, [37])  # the first single decode: the whole decoder
    assert gen.networks._halves is False
    halves = gen.decode(one, [37])
    assert gen.networks._halves not in (None, False)
    np.testing.assert_allclose(halves[0], whole[0], rtol=0, atol=1e-4)
    assert halves[0].shape == (37, whole[0].shape[1])


def test_generate_runs_its_torch_work_on_one_thread_and_gives_the_threads_back(backends,
                                                                              monkeypatch
                                                                              ) -> None:
    """networks.TORCH_GLUE_THREADS: inside generate() the critic (torch) sees one torch
    thread, the torch networks of a large batch all of them; afterwards torch has its own
    count again."""
    from mlct.generate.backends.onnx import networks
    from mlct.generate.compose import critic as critic_module

    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    gen = load_onnx(folder, threads=2)
    gen.keep_going = False
    seen: dict[str, list[int]] = {"critic": [], "torch networks": []}
    best = critic_module.Critic.best

    def counting_best(self, *args, **kwargs):
        seen["critic"].append(torch.get_num_threads())
        return best(self, *args, **kwargs)

    torch_loop = networks.sample_loop

    def counting_loop(*args, **kwargs):
        seen["torch networks"].append(torch.get_num_threads())
        return torch_loop(*args, **kwargs)

    monkeypatch.setattr(critic_module.Critic, "best", counting_best)
    monkeypatch.setattr(networks, "sample_loop", counting_loop)
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        made = gen.generate(TEXTS[:1], lengths=[40], nfe=2, seed=3, candidates=4)
        assert torch.get_num_threads() == 2
        assert seen["critic"] == [1] and seen["torch networks"] == []
        want = backends[0].generate(TEXTS[:1], lengths=[40], nfe=2, seed=3, candidates=4)
        assert gap(want, made) < JOINTS_M
        count = -(-networks.TORCH_MIN_BATCH // 4)  # prompts of 4 candidates: a large batch
        gen.generate(TEXTS[:1] * count, lengths=[40] * count, nfe=2, seed=3, candidates=4)
        assert seen["torch networks"] == [2] and torch.get_num_threads() == 2
        # calls from several threads at once: the first in saves torch's count, the last one
        # out gives it back, whatever the order they leave in
        from mlct.generate.backends.onnx.networks import torch_glue

        first, second = torch_glue(1), torch_glue(1)
        first.__enter__()
        second.__enter__()
        assert torch.get_num_threads() == 1
        first.__exit__(None, None, None)  # the first out is not the last
        assert torch.get_num_threads() == 1
        second.__exit__(None, None, None)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(previous)


def test_the_generators_spinning_reaches_its_steps_and_its_text_encoder(backends) -> None:
    """OnnxNetworks.spinning: False or True forces the steps' sessions (batch 1 and
    larger) and the text encoder's, None gives them back to the machine's load."""

    folder = Path(backends[1].networks.graphs.denoiser).parent.parent
    gen = load_onnx(folder, threads=2)
    gen.networks.spinning = False
    assert gen.text_encoder.spinning is False  # made after: it takes the generator's
    rows = torch.as_tensor(gen.encode_text(TEXTS[:1])).repeat_interleave(3, dim=0)
    for _ in range(2):
        gen.sample_latents(rows, 2, [1, 2, 3])
        gen.sample_latents(rows[:1], 2, [1])
    assert {key[4] for key in gen.networks.graph_sessions.sessions} == {False}
    gen.networks.spinning = True
    assert gen.text_encoder.spinning is True and gen.networks.spinning is True
    gen.sample_latents(rows, 2, [1, 2, 3])
    gen.sample_latents(rows[:1], 2, [1])
    assert (2, 2, False, True, True) in gen.networks.graph_sessions.sessions and (2, 2, True, True, True) in gen.networks.graph_sessions.sessions
    gen.networks.spinning = None
    assert gen.text_encoder.spinning is None and gen.networks.spinning is None
