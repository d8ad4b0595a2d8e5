"""backend="auto" (generate/backends/auto.py): onnx where it can run, its graphs found in the
model directory (int8 ones too, the bundled model's shipped ones) or made once into the cache,
atomically; torch otherwise; --verbose says which. onnx-int8 asked for by name."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import mlct
from mlct.cli import main
from mlct.errors import MlctError
from mlct.generate.backends import auto as auto_backend
from mlct.generate.backends.onnx.bundle import MANIFEST
from mlct.generate.backends.onnx.convert import convert_to_onnx
from mlct.generate.bundle import BUNDLE_FILES, OPTIONAL_FILES, bundled_model_dir

pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def plain(tmp_path_factory) -> Path:
    """The bundled model without the graphs it ships (a model `mlct export` wrote)."""
    folder = tmp_path_factory.mktemp("plain")
    for name in BUNDLE_FILES + OPTIONAL_FILES:
        shutil.copy2(bundled_model_dir() / name, folder / name)
    return folder


@pytest.fixture(scope="module")
def cache(tmp_path_factory, plain) -> Path:
    """A fresh MLCT_CACHE in which auto has converted `plain` once."""
    folder = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("MLCT_CACHE", str(folder))
        patch.delenv("MLCT_BACKEND")
        gen = mlct.load(plain)
    assert gen.backend == "onnx", gen.backend_note
    return folder


@pytest.fixture()
def auto(cache, monkeypatch) -> Path:
    monkeypatch.setenv("MLCT_CACHE", str(cache))
    monkeypatch.delenv("MLCT_BACKEND")
    return cache


def test_first_use_converts_into_the_cache_atomically_and_once(auto, plain, monkeypatch
                                                               ) -> None:
    entries = list((auto / "onnx").iterdir())
    assert len(entries) == 1 and (entries[0] / MANIFEST).is_file()  # no partial directory left
    assert entries[0] == auto_backend.default_graph_dir(plain)
    assert entries[0] != auto_backend.default_graph_dir(plain, int8=True)

    def fail(*args):
        raise AssertionError("converted again")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs", fail)
    gen = mlct.load(plain)
    assert gen.backend == "onnx" and str(entries[0]) in gen.backend_note
    assert gen.backend_note.startswith("onnx (auto: ONNX Runtime")


def test_the_bundled_model_runs_its_shipped_graphs_without_converting(tmp_path, monkeypatch
                                                                     ) -> None:
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path))
    monkeypatch.delenv("MLCT_BACKEND")

    def fail(*args):
        raise AssertionError("converted")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs", fail)
    for backend in ("auto", "onnx"):
        gen = mlct.load(backend=backend)
        assert gen.backend == "onnx"
        assert Path(gen.networks.graphs.denoiser).parent == bundled_model_dir() / "onnx"
    assert not (tmp_path / "onnx").exists()


def _gap(want, got) -> tuple[float, float]:
    """Mean and largest distance (m) between the joints of two lists of motions."""
    gaps = np.concatenate([np.linalg.norm(a.joints - b.joints, axis=-1).ravel()
                           for a, b in zip(want, got)])
    return float(gaps.mean()), float(gaps.max())


def test_auto_gives_the_torch_backends_motions(auto) -> None:
    texts, lengths = ["a person walks forward", "someone jumps"], [120, 40]
    want = mlct.load(backend="torch").generate(texts, lengths=lengths, nfe=5, seed=2)
    for _ in range(2):  # the step loop, then the sampler graph
        got = mlct.load().generate(texts, lengths=lengths, nfe=5, seed=2)
        assert _gap(want, got)[1] < 1e-3


def test_onnx_int8_moves_the_joints_by_millimetres_not_metres(auto) -> None:
    """Asked for by name, the int8 denoiser: other motions than float32's, near them on
    average for these prompts (docs/performance.md measures it on the benchmark)."""
    texts = ["a person walks forward", "a man waves his right hand"]
    want = mlct.load(backend="torch").generate(texts, lengths=[120, 80], nfe=5, seed=2,
                                               candidates=1)
    gen = mlct.load(backend="onnx-int8")
    assert gen.backend == "onnx-int8" and gen.backend_note == "onnx-int8 (asked for)"
    assert gen.networks.graphs.manifest["int8"] == ["denoiser"]
    for _ in range(2):
        got = gen.generate(texts, lengths=[120, 80], nfe=5, seed=2, candidates=1)
        assert 0 < _gap(want, got)[0] < 0.02  # 6 mm with blocks of 32 (2026-11-26)


def test_graphs_in_the_model_directory_come_first(auto, tmp_path) -> None:
    model = convert_to_onnx(bundled_model_dir(), tmp_path / "model", read_only=True)
    gen = mlct.load(model)  # float32 graphs put there by `mlct convert`: used as they are
    assert gen.backend == "onnx" and str(model / "onnx") in gen.backend_note
    model8 = convert_to_onnx(bundled_model_dir(), tmp_path / "model8", read_only=True, int8=True)
    gen = mlct.load(model8)
    assert gen.backend == "onnx-int8" and str(model8 / "onnx") in gen.backend_note


def test_onnx_by_name_on_a_model_without_graphs_takes_the_caches(auto, plain, monkeypatch
                                                                  ) -> None:
    """backend="onnx" on a model that holds no graphs: the cache's float32 graphs, made by the
    first use (the fixture's) and not again."""
    def fail(*args):
        raise AssertionError("converted again")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs", fail)
    gen = mlct.load(plain, backend="onnx")
    assert gen.backend_note == "onnx (asked for)" and "int8" not in gen.networks.graphs.manifest
    assert Path(gen.networks.graphs.denoiser).parent == auto_backend.default_graph_dir(plain)


def test_threads_set_torch_and_every_graph(auto, tmp_path, capsys) -> None:
    """threads= (--threads): PyTorch's intra-op threads and ONNX Runtime's per graph; a count
    below 1 or not a whole number is a one-line error (exit 2 in the CLI)."""
    import torch

    before = torch.get_num_threads()
    try:
        gen = mlct.load(backend="onnx", threads=1)
        assert torch.get_num_threads() == 1 and gen.networks.threads == 1
        assert gen.text_encoder.threads == 1
        assert gen.ae.session.get_session_options().intra_op_num_threads == 1
        assert mlct.load(threads=2).networks.threads == 2  # auto: onnx here
        for bad in (0, -1, 1.5, "2", True):
            with pytest.raises(MlctError, match="threads must be a whole number of at least 1"):
                mlct.load(threads=bad)
        out = tmp_path / "x.npy"
        for threads in ("0", "two"):  # a usage error: argparse exits with 2
            with pytest.raises(SystemExit) as exited:
                main(["generate", "a person walks forward", "--threads", threads,
                      "--out", str(out)])
            assert exited.value.code == 2
        assert "argument --threads: at least 1 thread, got 0" in capsys.readouterr().err
        assert main(["generate", "a person walks forward", "--seconds", "1", "--seed", "0",
                     "--threads", "1", "--out", str(out), "--quiet"]) == 0
        assert np.load(out).shape == (20, 22, 3)
    finally:
        torch.set_num_threads(before)


def test_a_dtype_or_device_onnx_cannot_run_is_refused_before_converting(tmp_path,
                                                                         monkeypatch) -> None:
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path))  # an empty cache: a conversion would start

    def fail(*args):
        raise AssertionError("converted for a dtype or device it cannot run")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs", fail)
    for backend in ("onnx", "onnx-int8"):
        with pytest.raises(MlctError, match="runs float32 graphs; dtype 'bfloat16'"):
            mlct.load(backend=backend, dtype="bfloat16")
        with pytest.raises(MlctError, match="CUDA is not available|runs on the CPU, not 'cuda'"):
            mlct.load(backend=backend, device="cuda")


def test_a_concurrent_conversion_keeps_the_first(tmp_path, monkeypatch) -> None:
    entry = tmp_path / "onnx" / "key"

    # it renames its entry in meanwhile
    def other_process_finishes_first(model_dir, into, int8=False):
        entry.mkdir(parents=True)
        (entry / MANIFEST).write_text("theirs")
        (Path(into) / MANIFEST).write_text("ours")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs",
                        other_process_finishes_first)
    assert auto_backend.convert_into_cache(bundled_model_dir(), entry) == entry
    assert (entry / MANIFEST).read_text() == "theirs"
    assert [p.name for p in entry.parent.iterdir()] == ["key"]  # ours removed


def test_a_failed_conversion_leaves_nothing_and_falls_back(tmp_path, plain, monkeypatch
                                                           ) -> None:
    monkeypatch.setenv("MLCT_CACHE", str(tmp_path))
    monkeypatch.delenv("MLCT_BACKEND")

    def broken(model_dir, into, int8=False):
        (Path(into) / "half.onnx").write_text("x")
        raise MlctError("the ONNX graph differs from the torch network")

    monkeypatch.setattr("mlct.generate.backends.onnx.convert.write_onnx_graphs", broken)
    gen = mlct.load(plain)
    assert gen.backend == "torch" and "converting to ONNX failed" in gen.backend_note
    assert list((tmp_path / "onnx").iterdir()) == []


@pytest.mark.parametrize("setup, reason", [
    ({"dtype": "bfloat16"}, "dtype bfloat16"),
    ({"modules": {"onnxruntime": None}}, "onnxruntime is not installed"),
])
def test_auto_falls_back_to_torch(auto, monkeypatch, setup, reason) -> None:
    for name, module in setup.get("modules", {}).items():
        monkeypatch.setitem(sys.modules, name, module)
    gen = mlct.load(dtype=setup.get("dtype", "float32"))
    assert gen.backend == "torch" and reason in gen.backend_note


def test_environment_overrides_auto(auto, monkeypatch) -> None:
    monkeypatch.setenv("MLCT_BACKEND", "torch")
    assert mlct.load().backend_note == "torch ($MLCT_BACKEND)"
    monkeypatch.setenv("MLCT_BACKEND", "tensorflow")
    with pytest.raises(MlctError, match=r"unknown backend 'tensorflow' in \$MLCT_BACKEND"):
        mlct.load()


def test_cli_verbose_says_which_backend(auto, tmp_path, capsys) -> None:
    out = tmp_path / "x.npy"
    assert main(["generate", "a person walks forward", "--seconds", "1", "--seed", "0",
                 "--out", str(out), "--quiet", "--verbose"]) == 0
    err = capsys.readouterr().err
    assert "mlct: backend onnx (auto: ONNX Runtime" in err
    from mlct.generate.backends.onnx.networks import TORCH_MIN_BATCH

    assert f"batches of {TORCH_MIN_BATCH} or more latents on the torch networks" in err
    assert np.load(out).shape == (20, 22, 3)
    assert main(["generate", "a person walks forward", "--seconds", "1", "--seed", "0",
                 "--out", str(out), "--quiet", "--verbose", "--backend", "torch"]) == 0
    err = capsys.readouterr().err
    assert "mlct: backend torch (asked for)" in err and "torch networks" not in err


def test_auto_on_what_is_not_a_model_says_what_is_wrong(auto, tmp_path) -> None:
    with pytest.raises(MlctError, match="no such model directory"):
        mlct.load(tmp_path / "missing")
    with pytest.raises(MlctError, match="not an mlct model"):
        mlct.load(tmp_path)
