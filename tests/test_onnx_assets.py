"""The ONNX graphs shipped with the bundled model (mlct/onnx_assets.py writes them): made from the
weights beside them, read by the loader, the same motions as the torch backend for the same
seed, and the sampler's step coefficients of every step count as the torch sampler computes
them."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from mlct.errors import MlctError
from mlct.onnx_io import external_weights, safetensors_header_digest, session, weights_recipe
from mlct.shipped import (CRITIC_WEIGHTS, MINILM_DIR, MINILM_WEIGHTS, MODEL_DIR, SHIPPED_DIR,
                          TEXT_ENCODER_WEIGHTS, file_digest)

REMAKE = "remake them: python -m mlct.onnx_assets"


def _manifest() -> dict:
    return json.loads((SHIPPED_DIR / "onnx.json").read_text(encoding="utf-8"))


def test_shipped_graphs_were_made_from_the_bundled_weights():
    manifest = _manifest()
    assert manifest["weights_sha256"] == file_digest(MODEL_DIR / "model.safetensors"), REMAKE
    assert manifest[TEXT_ENCODER_WEIGHTS] == file_digest(MINILM_DIR / MINILM_WEIGHTS), REMAKE
    assert manifest[CRITIC_WEIGHTS] == file_digest(MODEL_DIR / "critic.safetensors"), REMAKE
    for name in manifest["graphs"].values():
        assert (SHIPPED_DIR / name).is_file()
    assert "int8" not in manifest  # the float32 graphs: auto's, the torch backend's motions


def test_the_loader_trusts_the_shipped_digests_and_checks_a_copys(tmp_path, monkeypatch):
    """The digests above are checked here, not at every load of the bundled model (~10-20 ms of
    hashing at a cold start); a copy of the model is checked against its graphs' manifest."""
    from mlct.generate.backends.onnx import bundle

    def hashed(model_dir):
        raise AssertionError(f"hashed {model_dir}")

    with monkeypatch.context() as patched:
        patched.setattr(bundle, "weights_digest", hashed)
        assert bundle.read_onnx(MODEL_DIR, "minilm+sides").shipped
    copy = tmp_path / "model"
    shutil.copytree(MODEL_DIR, copy)
    graphs = bundle.read_onnx(copy, "minilm+sides")
    assert not graphs.shipped
    (copy / "model.safetensors").write_bytes(b"other weights")
    with pytest.raises(MlctError, match="made from another"):
        bundle.read_onnx(copy, "minilm+sides")


def test_text_encoder_graph_reads_its_weights_from_the_shipped_minilm():
    graph = SHIPPED_DIR / _manifest()["graphs"]["text_encoder"]
    recipe = json.loads(weights_recipe(graph).read_text(encoding="utf-8"))
    assert (graph.parent / recipe["safetensors"]).resolve() == (MINILM_DIR / MINILM_WEIGHTS)
    assert recipe["header_sha256"] == safetensors_header_digest(MINILM_DIR / MINILM_WEIGHTS)
    assert graph.stat().st_size < 1_000_000  # the weights are not a second time in the graph
    names, values = external_weights(graph)
    assert len(names) == len(recipe["initializers"]) == 6  # the attentions' q, k, v joined
    import onnx

    in_file = [i for i in onnx.load(str(graph), load_external_data=False).graph.initializer
               if {e.key: e.value for e in i.external_data}.get("location") == MINILM_WEIGHTS]
    assert len(in_file) >= 6 * 3  # each layer's other products, read by ONNX Runtime


def test_externalized_weights_give_the_graphs_results_to_the_bit(tmp_path):
    """A tensor as it is and a transposed one (its MatMul a FusedMatMul) are read from the file
    by ONNX Runtime, a joined one is built by the recipe: the same results as the weights
    stored in the graph."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper
    from safetensors.numpy import save_file

    from mlct.onnx_io import externalize_weights

    rng = np.random.default_rng(0)
    a, b, c = (rng.standard_normal((8, 16)).astype(np.float32) for _ in range(3))
    save_file({"a": a, "b": b, "c": c, "e": a.copy() * 2}, str(tmp_path / "w.safetensors"))
    weights = {"a_t": a.T, "bc": np.concatenate([b.T, c.T], axis=1), "e": a * 2}
    nodes = [helper.make_node("MatMul", ["x", "a_t"], ["y"]),  # (3, 16) @ (16, 8)
             helper.make_node("MatMul", ["y", "e"], ["z"]),  # (3, 8) @ (8, 16): as it is
             helper.make_node("MatMul", ["z", "bc"], ["out"])]  # (3, 16) @ (16, 16)
    model = helper.make_model(helper.make_graph(
        nodes, "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [3, 16])],
        [helper.make_tensor_value_info("out", TensorProto.FLOAT, [3, 16])],
        [numpy_helper.from_array(np.ascontiguousarray(v), k) for k, v in weights.items()]),
        opset_imports=[helper.make_opsetid("", 17)])
    folder = tmp_path / "graphs"
    folder.mkdir()
    onnx.save(model, str(folder / "g.onnx"))
    x = {"x": rng.standard_normal((3, 16)).astype(np.float32)}
    (whole,) = session(folder / "g.onnx", threads=1).run(None, x)
    recipe = json.loads(externalize_weights(folder / "g.onnx", tmp_path / "w.safetensors",
                                            "../w.safetensors", min_size=1).read_text())
    assert [e["name"] for e in recipe["initializers"]] == ["bc"]
    ops = [n.op_type for n in onnx.load(str(folder / "g.onnx"), load_external_data=False
                                        ).graph.node]
    assert ops == ["FusedMatMul", "MatMul", "MatMul"]
    (read,) = session(folder / "g.onnx", threads=1).run(None, x)
    assert np.array_equal(read, whole)


def test_text_encoder_graph_against_the_torch_network():
    pytest.importorskip("torch")
    from mlct.text.minilm import MiniLMEncoder

    encoder = MiniLMEncoder(MINILM_DIR, name="minilm")
    ids, mask = encoder._pad([[101, 1037, 2711, 7365, 2830, 102], [101, 1037, 102]])
    pooled, states = encoder.network(ids, mask)
    graph = SHIPPED_DIR / _manifest()["graphs"]["text_encoder"]
    got = session(graph, threads=1).run(None, {"ids": ids.numpy(), "mask": mask.numpy()})
    assert np.abs(got[0] - pooled.numpy()).max() < 1e-5
    assert np.abs(got[1] - states.numpy()).max() < 1e-4


def test_critic_graph_against_the_torch_critic():
    torch = pytest.importorskip("torch")
    from mlct.generate.compose.critic import read_critic

    meta = json.loads((MODEL_DIR / "config.json").read_text(encoding="utf-8"))
    ae = meta["config"]["ae"]
    critic = read_critic(MODEL_DIR, meta["text_encoder"], meta["text_dim"],
                         ae["n_tokens"] * ae["latent_dim"])
    probe = torch.Generator().manual_seed(1)
    z = torch.randn(16, ae["n_tokens"], ae["latent_dim"], generator=probe)
    frames = torch.randint(20, 197, (16,), generator=probe).float()
    text = torch.nn.functional.normalize(torch.randn(16, meta["text_dim"], generator=probe), dim=1)
    graph = SHIPPED_DIR / _manifest()["graphs"]["critic"]
    (got,) = session(graph, threads=1).run(None, {"z": z.numpy(), "frames": frames.numpy(),
                                                  "text": text.numpy()})
    assert np.abs(got - critic.network.score(z, frames, text).numpy()).max() < 1e-5


def test_the_step_table_holds_the_torch_samplers_coefficients():
    pytest.importorskip("torch")
    from mlct.config import config_from_dict
    from mlct.generate.backends.onnx.sampler import (STEPS_TABLE, read_steps_table,
                                                     step_coefficients)
    from mlct.generate.samplers import ConsistencySampler

    meta = json.loads((MODEL_DIR / "config.json").read_text(encoding="utf-8"))
    sampler = ConsistencySampler(config_from_dict(meta["config"]))
    assert _manifest()["steps_table"] == STEPS_TABLE
    for steps in range(1, sampler.max_steps + 1):
        table = read_steps_table(SHIPPED_DIR / STEPS_TABLE, steps)
        want = step_coefficients(sampler, steps)
        # Torch's vectorised trigonometry differs by an ulp or two from one CPU's kernels to
        # another's (AVX2 against AVX-512), so the table holds the coefficients to float
        # precision, not bit for bit.
        for k in ("times", "coef"):
            np.testing.assert_allclose(table[k], want[k], rtol=1e-6, atol=1e-7,
                                       err_msg=f"{k} of {steps} steps")
    assert read_steps_table(SHIPPED_DIR / STEPS_TABLE, sampler.max_steps + 1) is None


def test_a_weights_file_other_than_the_recipes_is_refused(tmp_path):
    graph = SHIPPED_DIR / _manifest()["graphs"]["text_encoder"]
    copy = tmp_path / "onnx" / graph.name
    copy.parent.mkdir()
    shutil.copyfile(graph, copy)
    recipe = json.loads(weights_recipe(graph).read_text(encoding="utf-8"))
    recipe["safetensors"] = "../other.safetensors"
    weights_recipe(copy).write_text(json.dumps(recipe), encoding="utf-8")
    with pytest.raises(MlctError, match="missing"):
        external_weights(copy)
    from safetensors.numpy import save_file

    save_file({"x": np.zeros(3, np.float32)}, str(tmp_path / "other.safetensors"))
    with pytest.raises(MlctError, match="not the weights file"):
        external_weights(copy)


def test_bundled_model_runs_on_the_shipped_graphs_with_torchs_motions(monkeypatch):
    torch = pytest.importorskip("torch")
    import mlct

    monkeypatch.delenv("MLCT_BACKEND")  # the suite pins torch (conftest.py); auto is asked

    onnx = mlct.load(backend="auto", threads=1)
    assert onnx.backend == "onnx" and str(SHIPPED_DIR) in onnx.backend_note
    reference = mlct.load(backend="torch")
    torch.set_num_threads(1)
    for text in ("a person waves with the left hand", "a person walks forward, then jumps"):
        a = onnx.generate(text, seconds=3, seed=11)[0].joints
        b = reference.generate(text, seconds=3, seed=11)[0].joints
        assert a.shape == b.shape
        assert np.abs(a - b).max() < 1e-4  # metres: the same motion up to float rounding
