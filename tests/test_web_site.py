"""The static site's Python side, without a browser: the portable noise (its numbers are the
page's: tests/test_web_static_e2e.py checks them in Chromium), graphs stored as float16 with
nothing changed, and `mlct export-web`'s refusals (before any work, nothing half-written)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from mlct.cli import main
from mlct.diffusion.samplers import draw_noise
from mlct.errors import MlctError
from mlct.generate.samplers.portable_noise import PortableNoise, seed_key


def test_portable_noise_is_a_seeded_standard_normal_stream() -> None:
    z = PortableNoise(0).normals(200_000)
    assert z.dtype == np.float32
    assert abs(z.mean()) < 0.01 and abs(z.std() - 1) < 0.01
    assert abs((z > 1.96).mean() - 0.025) < 0.002  # a normal's tail, not just its moments
    # the first draws of seed 0, as noise.js gives them in the page (checked there)
    np.testing.assert_allclose(z[:4], [-0.22490984, -1.020364, -0.32291436, -1.0482278],
                               rtol=1e-6)
    again = PortableNoise(0)
    assert np.array_equal(np.concatenate([again.normals(6), again.normals(6)]), z[:12])
    assert not np.array_equal(PortableNoise(1).normals(6), z[:6])
    assert seed_key(2**40 + 5) != seed_key(5)  # the high 32 bits count
    with pytest.raises(ValueError, match="seed"):
        PortableNoise(-1)


def test_the_samplers_draw_the_portable_noise() -> None:
    got = draw_noise((2, 3, 4), PortableNoise(3), torch.empty(0))
    assert got.shape == (2, 3, 4) and got.dtype == torch.float32
    assert np.array_equal(got.numpy().reshape(-1), PortableNoise(3).normals(24))


def test_float16_storage_keeps_every_number(tmp_path) -> None:
    pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    from mlct.generate.backends.onnx.compact import float16_storage
    from mlct.onnx_io import export_graph

    layer = torch.nn.Sequential(torch.nn.Linear(64, 128), torch.nn.GELU(), torch.nn.Linear(128, 32))
    with torch.no_grad():
        layer[0].weight.copy_(layer[0].weight.half().float())  # float16 numbers in float32
        layer[2].weight.add_(1e-5)  # not float16 numbers: must stay float32
    x = torch.randn(5, 64)
    export_graph(layer, (x,), tmp_path / "f32.onnx", ["x"], ["y"], {"x": {0: "b"}, "y": {0: "b"}})
    assert float16_storage(tmp_path / "f32.onnx", tmp_path / "f16.onnx") == 1
    run = lambda name: ort.InferenceSession(str(tmp_path / name)).run(None, {"x": x.numpy()})[0]
    assert np.array_equal(run("f16.onnx"), run("f32.onnx"))
    saved = (tmp_path / "f32.onnx").stat().st_size - (tmp_path / "f16.onnx").stat().st_size
    assert saved > 64 * 128 * 2 * 0.9  # the converted weight's two bytes a number


def test_export_web_refuses_a_bad_out_or_vendor_before_any_work(tmp_path, capsys) -> None:
    from mlct.serve.site import export_site

    a_file = tmp_path / "site.txt"
    a_file.write_text("not a site")
    assert main(["export-web", "--out", str(a_file)]) == 2
    assert "site.txt is not a directory" in capsys.readouterr().err
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    with pytest.raises(MlctError, match="not an mlct web site"):
        export_site("bundled", full)
    assert (full / "keep.txt").read_text() == "mine"
    empty_vendor = tmp_path / "vendor"
    empty_vendor.mkdir()
    with pytest.raises(MlctError, match=r"no onnxruntime-web-[0-9.]+\.tgz .*npm pack"):
        export_site("bundled", tmp_path / "site", vendor=empty_vendor)
    assert not (tmp_path / "site").exists()  # nothing half-written
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    assert main(["export-web", "--model", str(tmp_path / "nope"), "--out",
                 str(tmp_path / "s")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_int8_weights_are_int8_on_disk_and_close_in_use(tmp_path) -> None:
    pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    from mlct.generate.backends.onnx.compact import quantize_int8, quantize_int8_weights
    from mlct.onnx_io import export_graph

    torch.manual_seed(0)
    layer = torch.nn.Sequential(torch.nn.Linear(256, 512), torch.nn.Tanh(),
                                torch.nn.Linear(512, 64))
    x = torch.randn(8, 256)
    export_graph(layer, (x,), tmp_path / "f32.onnx", ["x"], ["y"], {"x": {0: "b"}, "y": {0: "b"}})
    assert quantize_int8_weights(tmp_path / "f32.onnx", tmp_path / "w8.onnx") == 2
    quantize_int8(tmp_path / "f32.onnx", tmp_path / "d8.onnx")
    run = lambda name: ort.InferenceSession(str(tmp_path / name)).run(None, {"x": x.numpy()})[0]
    exact = run("f32.onnx")
    size = lambda name: (tmp_path / name).stat().st_size
    for name in ("w8.onnx", "d8.onnx"):
        assert size(name) < 0.3 * size("f32.onnx")  # a byte a weight, not four
        error = np.abs(run(name) - exact).max() / np.abs(exact).max()
        assert 0 < error < 0.03, (name, error)
    # weight-only keeps float32 arithmetic: closer than int8 activations
    assert np.abs(run("w8.onnx") - exact).max() < np.abs(run("d8.onnx") - exact).max()


def test_int8_arithmetic_is_the_same_on_cpus_without_vnni(tmp_path) -> None:
    """The dynamic int8 graph as an AVX2-only CPU computes it (its kernel saturates pairs of
    products in int16: mlct/serve/site/int8_emulation.py): the same numbers as this CPU's. ONNX Runtime's
    own int8 weights, on this layer, came out 20 % off float32 there."""
    onnx = pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    from onnx import numpy_helper
    from onnxruntime.quantization import QuantType, quantize_dynamic

    from mlct.serve.site.int8_emulation import as_non_vnni
    from mlct.generate.backends.onnx.compact import quantize_int8
    from mlct.generate.backends.onnx.int8_pairs import max_pair
    from mlct.onnx_io import export_graph

    torch.manual_seed(0)
    layer = torch.nn.Sequential(torch.nn.Linear(256, 512), torch.nn.Tanh(),
                                torch.nn.Linear(512, 64))
    x = torch.randn(8, 256)
    export_graph(layer, (x,), tmp_path / "f32.onnx", ["x"], ["y"], {"x": {0: "b"}, "y": {0: "b"}})
    quantize_int8(tmp_path / "f32.onnx", tmp_path / "d8.onnx", ("MatMul", "Gemm"))
    quantize_dynamic(str(tmp_path / "f32.onnx"), str(tmp_path / "ort.onnx"), per_channel=True,
                     op_types_to_quantize=["MatMul", "Gemm"], weight_type=QuantType.QInt8)
    options = ort.SessionOptions()
    options.log_severity_level = 3  # the rewrite leaves the int8 weights unused
    run = lambda model: ort.InferenceSession(model.SerializeToString(), options).run(
        None, {"x": x.numpy()})[0]
    exact = layer(x).detach().numpy()
    error = lambda y: np.abs(y - exact).max() / np.abs(exact).max()
    ours, theirs = onnx.load(str(tmp_path / "d8.onnx")), onnx.load(str(tmp_path / "ort.onnx"))
    weights = [numpy_helper.to_array(i) for i in ours.graph.initializer
               if i.name.endswith("_quantized") and i.data_type == onnx.TensorProto.INT8]
    assert len(weights) == 2 and max(max_pair(w) for w in weights) <= 128  # 255 x 128 < 2^15
    (ours_non_vnni, n), (theirs_non_vnni, _) = as_non_vnni(ours), as_non_vnni(theirs)
    assert n == 2
    np.testing.assert_allclose(run(ours_non_vnni), run(ours), rtol=0, atol=1e-5)
    assert error(run(ours)) < 0.03 and error(run(ours_non_vnni)) < 0.03
    # the emulation is of something: ONNX Runtime's own weights differ there by far
    assert error(run(theirs)) < 0.03 < 0.1 < error(run(theirs_non_vnni))


def test_a_folder_that_is_no_site_is_refused_by_the_reference(tmp_path) -> None:
    from mlct.serve.site import load_site_reference

    with pytest.raises(MlctError, match="not an mlct web site"):
        load_site_reference(tmp_path)


def test_a_vendored_tarball_that_is_not_the_pinned_one_is_refused(tmp_path) -> None:
    from mlct.serve.site.vendor import copy_vendor_files, pins

    for pin in pins():
        (tmp_path / pin.tarball).write_bytes(b"not the package")
    with pytest.raises(MlctError, match="sha512 differs"):
        copy_vendor_files(tmp_path / "out", vendor=tmp_path)
    assert [p.name for p in pins()] == ["onnxruntime-web", "three", "gifenc"]
    assert all(p.integrity.startswith("sha512-") for p in pins())


def test_gzip_keeps_a_file_packed_only_when_it_shrinks_and_unpacks_the_same_bytes(tmp_path):
    import gc

    from mlct.serve.site.pack import gzip_file, is_gzip, remove_with, unpacked

    rng = np.random.default_rng(0)
    small = rng.integers(0, 4, 200_000, dtype=np.uint8).tobytes()  # 2 bits of 8: packs well
    noise = rng.integers(0, 256, 200_000, dtype=np.uint8).tobytes()  # does not
    (tmp_path / "a.onnx").write_bytes(small)
    (tmp_path / "b.onnx").write_bytes(noise)
    packed, plain = gzip_file(tmp_path / "a.onnx"), gzip_file(tmp_path / "b.onnx")
    assert packed.name == "a.onnx.gz" and is_gzip(packed) and not (tmp_path / "a.onnx").exists()
    assert plain.name == "b.onnx" and plain.read_bytes() == noise
    assert not (tmp_path / "b.onnx.gz").exists()
    assert packed.read_bytes() == gzip_file_copy(tmp_path, small)  # no time stamp: same bytes

    class Owner:
        pass

    owner = Owner()
    files, folder = unpacked({"a": packed, "b": plain})
    remove_with(owner, folder)
    assert files["a"].read_bytes() == small and files["b"] == plain
    assert folder.is_dir() and files["a"].parent == folder
    del owner
    gc.collect()
    assert not folder.exists()  # the unpacked copies go with their owner
    assert unpacked({"b": plain}) == ({"b": plain}, None)


def gzip_file_copy(tmp_path, data: bytes) -> bytes:
    from mlct.serve.site.pack import gzip_file

    (tmp_path / "again").mkdir()
    (tmp_path / "again" / "a.onnx").write_bytes(data)
    return gzip_file(tmp_path / "again" / "a.onnx").read_bytes()


def test_the_reference_makes_a_sequence_as_generate_chains_it() -> None:
    """The Python reference of the page (generate_with_portable_noise) splits a sequence as
    generate() does: the parts' shares from the duration model, part k drawn with seed + k
    at its share plus the next part's blend, chained by long_motion.chain_segments, planted."""
    import mlct
    from mlct.generate.compose.actions import split_actions
    from mlct.generate.compose.long_motion import chain_segments
    from mlct.serve.site.reference import generate_with_portable_noise
    from mlct.motion.foot_lock import lock_feet

    generator = mlct.load(backend="torch")
    text = "a person walks forward, then waves with the right hand"
    features, joints = generate_with_portable_noise(generator, text, 100, 3, 5)
    parts = split_actions(text)
    share = generator.part_frames(parts, 100)
    assert len(parts) == 2 and sum(share) == 100 and features is None and len(joints) == 100
    made = [generate_with_portable_noise(generator, p, n, 3, 5 + k, split_actions=False)
            for k, (p, n) in enumerate(zip(parts, [share[0] + 15, share[1]]))]
    lock, generator.foot_lock = generator.foot_lock, None  # the parts as decoded
    try:
        decoded = [generate_with_portable_noise(generator, p, len(m[1]), 3, 5 + k)[1]
                   for k, (p, m) in enumerate(zip(parts, made))]
    finally:
        generator.foot_lock = lock
    chained = chain_segments(decoded, 15, generator.skeleton)[0].astype(np.float32)
    expected = lock_feet(chained, generator.skeleton, generator.foot_lock)
    assert np.abs(joints - expected).max() < 1e-5
    # the walk walks and the wave raises the right wrist, in that order
    walked = np.linalg.norm(joints[share[0] - 1, 0, [0, 2]] - joints[0, 0, [0, 2]])
    right_wrist = generator.skeleton.joint_names.index("right_wrist")
    assert walked > 1.0 and joints[share[0] + 20:, right_wrist, 1].max() > 1.5
    assert joints[:share[0] - 10, right_wrist, 1].max() < 1.3
    # made whole, as the page did before, it is one motion of the whole text
    _, whole = generate_with_portable_noise(generator, text, 100, 3, 5, split_actions=False)
    assert np.abs(whole - joints).max() > 0.1


def test_the_site_description_carries_the_sequence_rules_and_durations() -> None:
    """model.json holds what static/compose.js and chain.js compute with, from their Python
    owners: compose's rules (one owner: a rule changed there is the page's too), the duration
    model without its fit record, the blend and the facing joints."""
    import mlct
    from mlct.generate.bundle import read_bundle
    from mlct.generate.compose.actions import portable_rules
    from mlct.generate.compose.long_motion import BLEND_SECONDS
    from mlct.serve.site.export import site_description

    folder = mlct.generate.bundle.bundled_model_dir()
    meta, tensors = read_bundle(folder)
    description = site_description(meta, tensors, folder, {}, (6, 64), "int8", "float16")
    assert description["sequence"]["rules"] == portable_rules()
    assert description["sequence"]["blend_seconds"] == BLEND_SECONDS
    durations = description["durations"]
    assert "fit" not in durations and len(durations["hidden_weight"]) == meta["text_dim"]
    assert set(durations["offsets"]) == {"first", "middle", "last"}
    assert description["skeleton"]["face_joints"] == [2, 1, 17, 16]
    json.dumps(description)  # plain JSON


def test_the_reference_makes_an_arm_action_apart_and_keeps_a_gait_going() -> None:
    """The page's Python reference follows generate() further: "jogs in place while clapping"
    is the jog with the clap's arms re-attached (control_fit.reattach), and a run asked for
    9.8 s, which the model stops after ~4 s, is made again as takes chained into one run that
    is still running until its last half second (generate/compose/keep_going.py)."""
    import mlct
    from mlct.generate.control.schema import part_joints
    from mlct.generate.control.fit import reattach
    from mlct.generate.compose.keep_going import ground_speed
    from mlct.serve.site.reference import _one_with_portable_noise, generate_with_portable_noise

    generator = mlct.load(backend="torch")
    lock, generator.foot_lock = generator.foot_lock, None  # compared as decoded and joined
    try:
        _, joints = generate_with_portable_noise(generator, "a person jogs in place while "
                                                 "clapping", 80, 3, 2, candidates=1)
        _, body = _one_with_portable_noise(generator, "a person jogs in place", 80, 3, 2)
        _, arms = _one_with_portable_noise(generator, "a person claps", 80, 3, 2)
        expected = reattach(arms.astype(np.float64), body.astype(np.float64),
                            part_joints("arms", generator.skeleton), generator.skeleton)
        assert np.abs(joints - expected).max() < 1e-5
        text = "a person runs forward"
        _, once = _one_with_portable_noise(generator, text, 196, 3, 4)
        _, kept = generate_with_portable_noise(generator, text, 196, 3, 4, candidates=1)
    finally:
        generator.foot_lock = lock
    once_speed, kept_speed = ground_speed(once, 20), ground_speed(kept, 20)
    assert once_speed[-20:].mean() < 0.3 * np.median(once_speed[10:70])  # stopped
    # still running over its last 2 s but the final half second, where the last take keeps its
    # stop (compose/keep_going.py; the run slows from its pace to rest in ~0.6 s on the last 2 bundles)
    assert kept_speed[-40:-10].mean() > 0.5 * np.median(kept_speed[10:70])
