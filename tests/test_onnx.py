"""The onnx backend (generate/backends/onnx/networks.py) against the torch backend: same seeds, same motions.

The bundled model is converted once (`mlct convert bundled --onnx --out DIR`); a random tiny
model covers what the bundled one does not use: the transformer decoder (frames free in the
graph), the DDIM sampler (two passes per step) and the "+tokens" text condition.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import mlct
from mlct.cli import main
from mlct.errors import MlctError
from mlct.generate.backends.onnx.bundle import MANIFEST, ONNX_DIR
from mlct.generate.backends.onnx.convert import convert_to_onnx
from mlct.generate.compose.generator import MotionGenerator
from mlct.generate.load import load_onnx
from mlct.generate.bundle import bundled_model_dir

from bundle_factory import random_bundle

pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

pytestmark = pytest.mark.usefixtures("one_thread")

JOINTS_M = 1e-3  # the most a joint may move between the backends, in metres
TEXTS = ["a person walks forward", "a person jumps up high", "someone waves with the left hand"]


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    return convert_to_onnx(bundled_model_dir(), tmp_path_factory.mktemp("onnx") / "model",
                           read_only=True)


@pytest.fixture(scope="module")
def backends(converted) -> tuple[MotionGenerator, MotionGenerator]:
    return mlct.load(converted), mlct.load(converted, backend="onnx")


def largest_gap(a, b) -> float:
    assert [m.joints.shape for m in a] == [m.joints.shape for m in b]
    return max(float(np.abs(x.joints - y.joints).max()) for x, y in zip(a, b))


def test_convert_copies_the_bundle_and_writes_three_graphs(converted) -> None:
    names = sorted(p.name for p in converted.iterdir())
    # the duration model, the critic and the text anchors travel with the weights (bundle.py)
    assert names == ["Mean.npy", "Std.npy", "config.json", "critic.safetensors", "durations.json",
                     "model.safetensors", ONNX_DIR, "text_anchors.safetensors"]
    assert sorted(p.name for p in (converted / ONNX_DIR).iterdir()) == [  # and the step table:
        "consistency_steps.npz", "decoder.onnx", "denoiser.onnx", MANIFEST, "text_encoder.onnx"]


@pytest.mark.parametrize("nfe", [1, 2, 5])
def test_same_seeds_give_the_same_motions(backends, nfe) -> None:
    torch_gen, onnx_gen = backends
    assert (torch_gen.backend, onnx_gen.backend) == ("torch", "onnx")
    lengths = [196, 60, 13]
    a = torch_gen.generate(TEXTS, lengths=lengths, nfe=nfe, seed=11)
    b = onnx_gen.generate(TEXTS, lengths=lengths, nfe=nfe, seed=11)
    assert [m.joints.shape[0] for m in b] == lengths
    assert largest_gap(a, b) < JOINTS_M
    for x, y in zip(a, b):
        np.testing.assert_allclose(y.features, x.features, atol=1e-3)
    other = onnx_gen.generate(TEXTS[:1], lengths=[60], nfe=nfe, seed=12)
    assert np.abs(other[0].joints - b[0].joints[:60]).max() > 0.01  # the seed matters


def test_text_embeddings_match_the_torch_encoder(backends) -> None:
    from mlct.text import load_text_encoder
    from mlct.text.minilm_onnx import OnnxMiniLMEncoder

    _, onnx_gen = backends
    texts = [*TEXTS, "", "café naïve 北京", "step " * 300]  # empty, unicode, truncated
    ours = onnx_gen.text_encoder.encode(texts)
    spec = onnx_gen.meta["text_encoder"]  # the bundled model's: 'minilm+sides' contrasts sides
    torch.testing.assert_close(ours, load_text_encoder(spec).encode(texts), rtol=0, atol=1e-5)
    # ... by ONNX Runtime's fused operators: one Attention per layer (write_minilm_graph)
    import onnx

    ops = [node.op_type for node in onnx.load(str(onnx_gen.networks.graphs.text_encoder)).graph.node]
    assert ops.count("Attention") == 6 and "Softmax" not in ops
    # its threads spin within a run and stop with it while the machine is idle beside them
    # (onnx_io.spin_now), and sleep while other processes keep its CPUs busy
    import mlct.onnx_io as onnx_io

    encoder = OnnxMiniLMEncoder(onnx_gen.networks.graphs.text_encoder, spec, threads=2)
    made_at_load = set(encoder._sessions)
    with pytest.MonkeyPatch.context() as patch:  # the first run: the session made at load,
        patch.setattr(onnx_io, "OTHER_LOAD", lambda: 0.0)  # whatever the load says then
        patch.setattr(onnx_io.os, "cpu_count", lambda: 2)
        encoder.encode(texts[:1])
    assert set(encoder._sessions) == made_at_load

    def spins() -> str:
        options = encoder.session.get_session_options()
        assert options.intra_op_num_threads == 2
        if options.get_session_config_entry("session.intra_op.allow_spinning") == "0":
            return "0"
        assert options.get_session_config_entry("session.force_spinning_stop") == "1"
        return "1"

    # others' load in logical CPUs (None: the machine does not say), the machine's CPUs
    for others, cores, want in ((0.05, 2, "1"), (1.0, 2, "0"), (0.05, 2, "1"), (None, 2, "0"),
                                (None, 8, "1"), (6.5, 8, "0"), (5.0, 8, "1")):
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(onnx_io.os, "cpu_count", lambda cores=cores: cores)
            patch.setattr(onnx_io, "OTHER_LOAD", lambda others=others: others)
            assert spins() == want, (others, cores)
            got = encoder.encode(texts[:2])  # the same vectors whichever session ran
        torch.testing.assert_close(got, ours[:2], rtol=0, atol=1e-5)
    assert set(encoder._sessions) == {False, True}  # each kind made once, then kept
    # the same graph serves "minilm+tokens": the token slots are filled around it
    tokens = OnnxMiniLMEncoder(onnx_gen.networks.graphs.text_encoder, "minilm+tokens")
    torch.testing.assert_close(tokens.encode(texts), load_text_encoder("minilm+tokens").encode(
        texts), rtol=0, atol=1e-4)


def test_other_load_is_the_machines_busy_time_less_this_process(monkeypatch) -> None:
    """onnx_io.OtherLoad: other processes' logical CPUs over the last window of at least
    LOAD_WINDOW_S, read again only when one has passed; None until two readings, and where the
    machine says nothing."""
    import mlct.onnx_io as onnx_io

    clock = [100.0]
    monkeypatch.setattr(onnx_io.time, "monotonic", lambda: clock[0])
    # (busy seconds of all CPUs since boot, this process's CPU seconds)
    readings = iter([(50.0, 10.0), (50.9, 10.5), (51.1, 10.5), (51.5, 11.0)])
    load = onnx_io.OtherLoad(lambda: next(readings))
    assert load() is None  # one reading: no window yet
    clock[0] += 1.0  # 0.9 s busy, 0.5 of them this process's: 0.4 CPUs elsewhere
    assert load() == pytest.approx(0.4)
    clock[0] += onnx_io.LOAD_WINDOW_S / 2  # within the window: the last figure, no reading
    assert load() == pytest.approx(0.4)
    clock[0] += onnx_io.LOAD_WINDOW_S  # 0.2 s busy over 1.5 windows, none of it ours
    assert load() == pytest.approx(0.2 / (1.5 * onnx_io.LOAD_WINDOW_S))
    clock[0] += 1.0  # the ticks' rounding: this process counted more than the machine
    assert load() == 0.0
    assert onnx_io.OtherLoad(lambda: None)() is None
    if Path("/proc/stat").exists():  # the real reader: busy time only grows
        first = onnx_io._cpu_seconds()
        sum(i * i for i in range(200_000))
        second = onnx_io._cpu_seconds()
        assert second[0] >= first[0] and second[1] >= first[1]


def test_chained_prompt_and_batch_independence(backends) -> None:
    torch_gen, onnx_gen = backends
    text = "a person walks forward, then sits down"  # made as two parts, chained
    assert largest_gap(torch_gen.generate(text, seconds=6, nfe=2, seed=3),
                       onnx_gen.generate(text, seconds=6, nfe=2, seed=3)) < JOINTS_M
    pair = onnx_gen.generate(TEXTS[:2], lengths=[40, 40], nfe=2, seed=[4, 5])
    alone = onnx_gen.generate(TEXTS[1:2], lengths=[40], nfe=2, seed=[5])
    np.testing.assert_allclose(pair[1].joints, alone[0].joints, atol=1e-4)


def test_cli_generate_with_the_onnx_backend(converted, tmp_path) -> None:
    args = ["generate", "a person jumps", "--model", str(converted), "--seconds", "2",
            "--nfe", "2", "--seed", "5", "--quiet"]
    assert main([*args, "--backend", "onnx", "--out", str(tmp_path / "onnx.npy")]) == 0
    assert main([*args, "--out", str(tmp_path / "torch.npy")]) == 0
    a, b = np.load(tmp_path / "torch.npy"), np.load(tmp_path / "onnx.npy")
    assert a.shape == b.shape == (40, 22, 3)
    assert np.abs(a - b).max() < JOINTS_M


def test_the_server_runs_on_the_onnx_backend(backends, converted, monkeypatch) -> None:
    import uvicorn
    from fastapi.testclient import TestClient

    from mlct.serve import run_server
    from mlct.serve.app import ServeSettings, create_app

    apps = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kwargs: apps.append(app))
    run_server(converted, backend="onnx", settings=ServeSettings(warmup=False))
    with TestClient(apps[0]) as client:  # `mlct serve --model DIR --backend onnx`
        assert client.get("/health").json()["model"]["backend"] == "onnx"
    torch_gen, onnx_gen = backends
    with TestClient(create_app(onnx_gen, ServeSettings(warmup=False))) as client:
        assert client.get("/health").json()["model"]["backend"] == "onnx"
        reply = client.post("/generate", json={"text": "a person runs.", "seconds": 2,
                                               "nfe": 2, "seed": 7})
    assert reply.status_code == 200, reply.text
    expected = torch_gen.generate(["a person runs."], lengths=[40], nfe=2, seed=[7])[0].joints
    assert np.abs(np.array(reply.json()["motions"][0]["joints"]) - expected).max() < JOINTS_M


# --- a random tiny model: transformer decoder, DDIM, "+tokens" ---------------------------------

@pytest.mark.slow
def test_transformer_decoder_ddim_and_token_condition(tmp_path) -> None:
    model = convert_to_onnx(random_bundle(tmp_path / "tiny", "ddim", "minilm+tokens"))
    torch_gen, onnx_gen = mlct.load(model), mlct.load(model, backend="onnx")
    for lengths in ([64, 9], [33]):  # frames free in the decoder's graph
        a = torch_gen.generate(TEXTS[: len(lengths)], lengths=lengths, nfe=3, seed=1)
        b = onnx_gen.generate(TEXTS[: len(lengths)], lengths=lengths, nfe=3, seed=1)
        assert largest_gap(a, b) < JOINTS_M


def test_fused_attention_keeps_a_transformer_decoders_padding(tmp_path, monkeypatch) -> None:
    """onnx_attention.fuse_attention(padded=True): the decoder's masked attentions become
    ONNX Runtime's Attention with the padding as its mask (in its session and in the sampler
    graph), the features those of the exported graph, padded frames 0; without `padded` a
    masked block is left alone; a graph the rewrite fails on is run as written."""
    import onnx
    import onnxruntime as ort

    from mlct.generate.backends.onnx.attention import fuse_attention

    model = convert_to_onnx(random_bundle(tmp_path / "tiny", "consistency", "minilm"))
    gen = load_onnx(model)
    layers, heads = gen.config.ae.layers, gen.config.ae.heads
    decoder = onnx.load(str(gen.networks.graphs.decoder))
    assert fuse_attention(decoder, heads) == 0  # masked: not the plain pattern
    assert fuse_attention(decoder, heads, padded=True) == layers
    kinds = [node.op_type for node in decoder.graph.node]
    assert kinds.count("Attention") == layers and "Softmax" not in kinds
    exported = ort.InferenceSession(str(gen.networks.graphs.decoder), providers=["CPUExecutionProvider"])
    fused = ort.InferenceSession(decoder.SerializeToString(), providers=["CPUExecutionProvider"])
    latent = np.random.default_rng(0).standard_normal((2, *gen.ae.latent_shape))
    valid = np.arange(64)[None] < np.array([[64], [9]])  # the second mostly padding
    feeds = {"latent": latent.astype(np.float32), "valid": valid}
    (want,), (got,) = exported.run(None, feeds), fused.run(None, feeds)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)
    assert np.abs(got[1, :9]).max() > 0.1 and not got[1, 9:].any()

    import mlct.generate.backends.onnx.networks as onnx_backend

    def cannot(*args, **kwargs):
        raise ValueError("not this graph")

    with monkeypatch.context() as patch:  # a graph the rewrite fails on loads as written
        patch.setattr(onnx_backend, "fuse_attention", cannot)
        plain = load_onnx(model).ae
    lengths = torch.tensor([64, 9])
    np.testing.assert_allclose(plain.decode(torch.from_numpy(feeds["latent"]), lengths, 64),
                               want, rtol=0, atol=1e-6)

    torch_gen = mlct.load(model)
    for threads in (1, 2):  # the decoder apart (one thread's steps) or in the sampler graph
        gen = load_onnx(model, threads=threads)
        gen.keep_going = False
        for _ in range(2):  # the second call builds the sampler graph
            got = gen.generate(TEXTS[:2], lengths=[64, 9], nfe=2, seed=1, candidates=1)
        graph = onnx.ModelProto.FromString(gen.networks.graph_sessions.fused[2]).graph
        assert sum(node.op_type == "Attention" for node in graph.node) >= layers
        want = torch_gen.generate(TEXTS[:2], lengths=[64, 9], nfe=2, seed=1, candidates=1)
        assert largest_gap(want, got) < JOINTS_M


def test_fused_attention_after_a_blockwise_quantized_product(tmp_path) -> None:
    """A q/k/v product quantized by blocks (MatMulNBits) stays; what follows it becomes
    ONNX Runtime's MultiHeadAttention. With float arithmetic in the product (accuracy_level
    1) the outputs are the exported graph's to float rounding. (The int8 arithmetic of
    `--int8` rounds each product's input to int8 too, so there float rounding can flip a
    step of it.)"""
    import logging

    import onnx
    import onnxruntime as ort
    from onnxruntime.quantization.matmul_nbits_quantizer import (
        DefaultWeightOnlyQuantConfig, MatMulNBitsQuantizer)

    from mlct.generate.backends.onnx.attention import fuse_attention

    gen = load_onnx(convert_to_onnx(random_bundle(tmp_path / "tiny",
                                                                 "consistency", "minilm")))
    quantizer = MatMulNBitsQuantizer(onnx.load(str(gen.networks.graphs.denoiser)),
                                     algo_config=DefaultWeightOnlyQuantConfig(
                                         block_size=32, is_symmetric=True, accuracy_level=1,
                                         bits=8))
    quiet = logging.getLogger("onnxruntime.quantization.matmul_nbits_quantizer")
    level = quiet.level
    quiet.setLevel(logging.WARNING)  # it logs every node it looks at
    try:
        quantizer.process()
    finally:
        quiet.setLevel(level)
    quantized = quantizer.model.model
    fused = onnx.ModelProto()
    fused.CopyFrom(quantized)
    layers = gen.config.denoiser.layers
    assert fuse_attention(fused, gen.config.denoiser.heads) == layers
    kinds = [node.op_type for node in fused.graph.node]
    assert kinds.count("MultiHeadAttention") == layers and "Softmax" not in kinds
    assert kinds.count("MatMulNBits") == sum(node.op_type == "MatMulNBits"
                                             for node in quantized.graph.node)
    rng = np.random.default_rng(0)
    feeds = {"x_t": rng.standard_normal((2, *gen.ae.latent_shape)).astype(np.float32),
             "t": np.array([500.0, 30.0], np.float32),
             "text": rng.standard_normal((2, int(gen.meta["text_dim"]))).astype(np.float32)}
    (want,), (got,) = (ort.InferenceSession(m.SerializeToString(),
                                            providers=["CPUExecutionProvider"]).run(None, feeds)
                       for m in (quantized, fused))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)
    assert np.abs(want).max() > 0.1


def test_conv_decoder_with_its_own_arm_pair(tmp_path) -> None:
    """ae.arm_tokens: the body and arm decoders' features put back in order inside the graph."""
    model = convert_to_onnx(random_bundle(
        tmp_path / "arms", "consistency", "minilm",
        ("ae.architecture=conv", "ae.channels=16", "ae.arm_tokens=1", "ae.arm_channels=8")))
    torch_gen, onnx_gen = mlct.load(model), mlct.load(model, backend="onnx")
    a = torch_gen.generate(TEXTS[:2], lengths=[64, 9], nfe=2, seed=1)
    b = onnx_gen.generate(TEXTS[:2], lengths=[64, 9], nfe=2, seed=1)
    assert largest_gap(a, b) < JOINTS_M
    # batch 1 on two threads: the steps apart, then the decoder's halves side by side
    # (backends/onnx/decoder_halves.py), operator for operator the whole decoder's arithmetic

    gen = load_onnx(model, threads=2)
    cond = torch.as_tensor(gen.encode_text(TEXTS[:1]))  # (numpy on this backend)
    for _ in range(2):  # the second call builds the sampler graph: the steps, then the halves
        features = gen.sample_features(cond, 2, [5], None, [37])[0]
    nets = gen.networks
    assert nets._halves is not None and nets._halves is not False
    assert features.shape[0] == 37
    z = gen.sample_latents(cond, 2, [5]).numpy() / np.float32(gen.config.schedule.latent_scale)
    valid = np.arange(37)[None] < 37
    (whole,) = nets.decoder.session.run(None, {"latent": z, "valid": valid})  # one session
    halves = nets._decoder_halves()
    np.testing.assert_allclose(halves(z, valid), whole * nets._std + nets._mean,
                               rtol=0, atol=1e-5)
    # on a machine whose other core is busy the halves run one after the other: the same bits
    assert np.array_equal(halves(z, valid, side_by_side=False), halves(z, valid))
    want = torch_gen.generate(TEXTS[:1], lengths=[37], nfe=2, seed=5, candidates=1)
    got = gen.generate(TEXTS[:1], lengths=[37], nfe=2, seed=5, candidates=1)
    assert largest_gap(want, got) < JOINTS_M
    # a forked child (multiprocessing on Linux) decodes too: it gets a worker thread of its own
    import multiprocessing

    if "fork" in multiprocessing.get_all_start_methods():
        _FORKED.update(gen=gen, cond=gen.encode_text(TEXTS[:1]))
        with multiprocessing.get_context("fork").Pool(1) as pool:
            child = pool.apply_async(_sample_in_child, (37,)).get(60)
        np.testing.assert_allclose(child, features, rtol=0, atol=1e-5)


_FORKED: dict = {}  # what a forked child inherits (a generator does not pickle)


def _sample_in_child(frames: int) -> np.ndarray:
    return _FORKED["gen"].sample_features(_FORKED["cond"], 2, [5], None, [frames])[0]


# --- bad input: one line naming the problem and the fix ----------------------------------------

def test_a_model_without_graphs_gets_them_from_the_cache(tmp_path, monkeypatch) -> None:
    """--backend onnx by name on a model without graphs makes them once into the cache, as
    auto does; without the onnx package that writes them, one line saying what to install."""
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path / "cache"))
    plain = random_bundle(tmp_path / "plain", "consistency", "minilm")
    gen = mlct.load(plain, backend="onnx")
    assert gen.backend_note == "onnx (asked for)" and "int8" not in gen.networks.graphs.manifest
    assert Path(gen.networks.graphs.denoiser).is_relative_to(tmp_path / "cache" / "onnx")
    assert not (plain / ONNX_DIR).exists()  # the model directory is not written
    want = mlct.load(plain, backend="torch").generate(["a person walks"], lengths=[40], seed=3,
                                                      candidates=1)
    got = gen.generate(["a person walks"], lengths=[40], seed=3, candidates=1)
    assert largest_gap(want, got) < 1e-3
    assert mlct.load(plain, backend="onnx").networks.graphs.denoiser == gen.networks.graphs.denoiser  # made once
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path / "empty"))
    monkeypatch.setitem(sys.modules, "onnx", None)
    with pytest.raises(MlctError, match=r"converting to ONNX failed \(writing ONNX graphs needs "
                                        r"the onnx package.*pip install"):
        mlct.load(plain, backend="onnx")
    assert main(["generate", "a person walks", "--model", str(plain), "--backend", "onnx",
                 "--out", str(tmp_path / "a.npy")]) == 2


def test_graphs_of_other_weights_are_refused(converted, tmp_path) -> None:
    import shutil

    copy = Path(shutil.copytree(converted, tmp_path / "copy"))
    manifest = json.loads((copy / ONNX_DIR / MANIFEST).read_text())
    (copy / ONNX_DIR / MANIFEST).write_text(json.dumps({**manifest, "weights_sha256": "0" * 64}))
    with pytest.raises(MlctError, match="made from another model.safetensors; make them with"):
        mlct.load(copy, backend="onnx")
    (copy / ONNX_DIR / "decoder.onnx").unlink()
    with pytest.raises(MlctError, match="the decoder graph is missing"):
        mlct.load(copy, backend="onnx")


def test_missing_onnxruntime_is_one_line_with_the_install_command(converted, monkeypatch
                                                                  ) -> None:
    with monkeypatch.context() as patch:
        patch.setitem(sys.modules, "onnxruntime", None)  # import onnxruntime -> ImportError
        with pytest.raises(MlctError, match=r"needs ONNX Runtime, which is not installed: "
                                            r"pip install onnxruntime==1\.32\.0"):
            mlct.load(converted, backend="onnx")
    with monkeypatch.context() as patch:
        patch.setitem(sys.modules, "onnx", None)
        with pytest.raises(MlctError, match=r"writing ONNX graphs needs the onnx package, which "
                                            r"is not installed: pip install onnxruntime"):
            convert_to_onnx(converted, converted.parent / "again")
    assert not (converted.parent / "again").exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"backend": "tensorrt"}, "unknown backend 'tensorrt'; choose one of auto, torch, onnx"),
    ({"backend": "onnx", "dtype": "bfloat16"}, "onnx backend runs float32 graphs"),
    ({"backend": "onnx", "device": "cuda"}, "CUDA is not available|runs on the CPU"),
])
def test_backend_options_that_cannot_work(converted, kwargs, message) -> None:
    with pytest.raises(MlctError, match=message):
        mlct.load(converted, **kwargs)


def test_convert_refuses_what_it_should_not_write(tmp_path, capsys) -> None:
    assert main(["convert", "bundled", "--onnx"]) == 2
    assert "lives inside the mlct package: give --out DIR" in capsys.readouterr().err
    assert main(["convert", "bundled"]) == 2
    assert "say what to convert the model to: --onnx" in capsys.readouterr().err
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    assert main(["convert", "bundled", "--onnx", "--out", str(busy)]) == 2
    assert "exists and is not a model directory" in capsys.readouterr().err
    assert (busy / "notes.txt").read_text() == "mine"
    clip = random_bundle(tmp_path / "clip", "consistency", "clip:/nowhere")
    with pytest.raises(MlctError, match=r"runs the bundled MiniLM text encoders .*'clip:/nowhere'"):
        convert_to_onnx(clip)
    assert not (clip / ONNX_DIR).exists()


@pytest.fixture(scope="module")
def converted_int8(tmp_path_factory) -> Path:
    return convert_to_onnx(bundled_model_dir(), tmp_path_factory.mktemp("int8") / "model",
                           read_only=True, int8=True)


def test_int8_quantizes_the_denoiser_only_and_moves_the_joints_little(converted,
                                                                       converted_int8) -> None:
    import onnx

    manifest = json.loads((converted_int8 / ONNX_DIR / MANIFEST).read_text())
    assert manifest["int8"] == ["denoiser"]
    assert "int8" not in json.loads((converted / ONNX_DIR / MANIFEST).read_text())
    size = lambda d, g: (d / ONNX_DIR / g).stat().st_size  # noqa: E731
    assert size(converted_int8, "denoiser.onnx") < 0.5 * size(converted, "denoiser.onnx")
    assert size(converted_int8, "text_encoder.onnx") == size(converted, "text_encoder.onnx")
    full = mlct.load(converted, backend="onnx")
    small = mlct.load(converted_int8, backend="onnx")
    for _ in range(2):  # the second call runs the fused sampler graph built from the int8 one
        a = full.generate(TEXTS, seconds=4, seed=3, candidates=1)
        b = small.generate(TEXTS, seconds=4, seed=3, candidates=1)
    (graph,) = [onnx.ModelProto.FromString(g).graph for g in small.networks.graph_sessions.fused.values() if g]
    kinds = [node.op_type for node in graph.node]  # the int8 products' attentions fused
    per_pass = sum(node.op_type == "MatMulNBits" for node in onnx.load(
        str(converted_int8 / ONNX_DIR / "denoiser.onnx")).graph.node)
    steps = kinds.count("MatMulNBits") // per_pass
    assert kinds.count("MultiHeadAttention") == steps * small.config.denoiser.layers > 0
    gaps = [np.linalg.norm(x.joints - y.joints, axis=-1) for x, y in zip(a, b)]
    poses = [np.linalg.norm((x.joints - x.joints[:, :1]) - (y.joints - y.joints[:, :1]), axis=-1)
             for x, y in zip(a, b)]
    # docs/performance.md: ~1 mm mean and 8 mm at most here on the bundle of
    # 2026-11-26, 23 mm at most on the one of 2026-11-27 (per-column scales gave 9 mm on average
    # and up to 8 cm); quantization is not exact, but close on average. On the bundle of
    # 2026-11-28 (version 4 of the recipe) 3 mm on average, the walk 1-2 cm at most, but the
    # wave's and the jump's swings shifted in time by int8: 3-8 cm here, up to 14 cm on other
    # seeds (docs/model_card.md, "What it cannot do"): int8 stays opt-in
    assert manifest["int8_block"] == 32
    assert 0 < float(np.mean([g.mean() for g in gaps])) < 0.005
    assert float(np.mean([p.mean() for p in poses])) < 0.003
    assert float(gaps[0].max()) < 0.03  # the walk
    assert max(float(g.max()) for g in gaps) < 0.15


def test_controls_on_the_onnx_backend_and_guidance_refused(backends) -> None:
    """The default CPU backend meets a path and a keyframe as the torch one does (candidates
    and the correction need only the decoder's forward pass); guidance, which needs the
    decoder's gradients, is a typed error there rather than silently skipped."""
    from mlct.generate.control.schema import control_from_dict
    from mlct.generate.control.controlled import ControlMethod, generate_controlled

    torch_gen, onnx_gen = backends
    path = [[0.0, 0.0, 0], [0.2, 1.2, 40], [0.9, 2.2, 80], [1.9, 2.6, 119]]
    frames, target = [p[2] for p in path], np.array(path)[:, :2]
    made = [gen.generate("a person walks forward", lengths=120, seed=3,
                         control={"path": path})[0].joints for gen in (torch_gen, onnx_gen)]
    for joints in made:
        assert np.linalg.norm(joints[frames, 0][:, [0, 2]] - target, axis=1).max() < 0.01
        assert joints[:, 0, 1].min() > 0.5  # still a standing body, not a collapsed one
    # the same seed and candidates give the same motion on both, up to float noise
    assert np.abs(made[0] - made[1]).max() < 0.01
    control = control_from_dict({"path": path}, onnx_gen.skeleton).check(120, onnx_gen.skeleton)
    with pytest.raises(MlctError, match="torch"):
        generate_controlled(onnx_gen, "a person walks forward", 120, control, None, 3,
                            ControlMethod(guide=True))
