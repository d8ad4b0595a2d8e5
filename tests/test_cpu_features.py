"""bfloat16 on a CPU whose oneDNN has no bfloat16 kernels (mlct/cpu_features.py): the layers run
PyTorch's plain kernels instead of oneDNN's, a generator runs float32 and says so.

Such a CPU is simulated two ways: torch's check patched to answer False (in this process), and
oneDNN and ATen held to AVX2 by their own variables (a subprocess: they are read once, when the
kernels are first dispatched), which is what an AVX2-only x86-64 machine runs."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import warnings

import numpy as np
import pytest
import torch
from torch import nn

from mlct import cpu_features
from mlct.errors import MlctWarning
from mlct.nn import inference
from mlct.nn.inference import ChannelsLastConvs

# what an AVX2-only x86-64 runs: oneDNN's AVX2 kernels (no bf16) and ATen's AVX2 ones
AVX2_ONLY = {"ONEDNN_MAX_CPU_ISA": "AVX2", "ATEN_CPU_CAPABILITY": "avx2"}
x86_64 = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                            reason="ONEDNN_MAX_CPU_ISA=AVX2 names an x86-64 instruction set")


def _chain() -> nn.Sequential:
    torch.manual_seed(0)
    return nn.Sequential(nn.Conv1d(16, 32, 3, padding=1), nn.GELU(), nn.Upsample(scale_factor=2),
                         nn.Conv1d(32, 16, 3, padding=1)).eval()


def test_a_bfloat16_conv_stack_without_the_kernels_takes_the_plain_convolution(monkeypatch):
    chain = _chain()
    x = torch.randn(2, 16, 20)
    with torch.no_grad():
        want = chain(x)
    monkeypatch.setattr(cpu_features, "onednn_bf16", lambda: False)

    def refused(*args, **kwargs):
        raise RuntimeError("mkldnn_convolution: bf16 path needs the cpu support ...")

    # oneDNN's fused op is what refuses bfloat16 there: it must not be called at all
    monkeypatch.setattr(inference, "_fused_conv", lambda: refused)
    with torch.no_grad():
        got = ChannelsLastConvs(chain, torch.bfloat16)(x)
        float32 = ChannelsLastConvs(chain, torch.float32)
        with pytest.raises(RuntimeError, match="bf16 path"):
            float32(x)  # float32 still takes oneDNN's op (every x86-64 and ARM64 CPU runs it)
    assert got.dtype == torch.float32 and got.shape == want.shape
    torch.testing.assert_close(got, want, atol=0.05, rtol=0.05)  # bfloat16's rounding only


def test_kernel_dtype_changes_bfloat16_on_such_a_cpu_only(monkeypatch):
    monkeypatch.setattr(cpu_features, "onednn_bf16", lambda: False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MlctWarning)
        for dtype in ("float32", torch.float32, "int4", None):
            assert cpu_features.kernel_dtype(dtype, "cpu") == dtype
        assert cpu_features.kernel_dtype("bfloat16", "bogus") == "bfloat16"  # said by the caller
    with pytest.warns(MlctWarning, match=r"^bfloat16 needs a CPU with .*; running float32"):
        assert cpu_features.kernel_dtype(torch.bfloat16, "cpu") == torch.float32
    monkeypatch.setattr(cpu_features, "onednn_bf16", lambda: True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MlctWarning)
        assert cpu_features.kernel_dtype("bfloat16", "cpu") == "bfloat16"


def test_the_feature_named_is_the_architectures(monkeypatch):
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert cpu_features.bf16_feature() == "the BF16 extension"
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    assert "AVX-512" in cpu_features.bf16_feature()


def _run_avx2(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, **AVX2_ONLY, "MLCT_BACKEND": "torch", "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=300)


@x86_64
def test_oneDNN_held_to_avx2_has_no_bf16_and_the_layers_still_run():
    done = _run_avx2(
        "import torch\n"
        "from torch import nn\n"
        "from mlct import cpu_features\n"
        "from mlct.nn.inference import ChannelsLastConvs, for_inference\n"
        "print(cpu_features.onednn_bf16())\n"
        "chain = nn.Sequential(nn.Conv1d(8, 8, 3, padding=1), nn.GELU()).eval()\n"
        "net = for_inference(nn.Sequential(nn.Linear(8, 8)), 'bfloat16')\n"
        "with torch.no_grad():\n"
        "    print(ChannelsLastConvs(chain, torch.bfloat16)(torch.randn(1, 8, 5)).shape)\n"
        "    print(net(torch.randn(2, 8)).dtype)\n")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["False", "torch.Size([1, 8, 5])", "torch.float32"]


@x86_64
@pytest.mark.slow
def test_generate_bfloat16_on_avx2_kernels_is_float32_with_one_note(tmp_path):
    """The whole command on the kernels an AVX2-only CPU has: before, 53 lines of oneDNN's
    traceback; now one note, and float32's motion."""
    outs = {dtype: tmp_path / f"{dtype}.npy" for dtype in ("bfloat16", "float32")}
    done = _run_avx2(
        "import sys\n"
        "from mlct.cli import main\n"
        f"a = main(['generate', 'a person walks', '--seconds', '2', '--seed', '4', '--nfe', '2',"
        f" '--device', 'cpu', '--dtype', 'bfloat16', '--out', {str(outs['bfloat16'])!r}])\n"
        f"b = main(['generate', 'a person walks', '--seconds', '2', '--seed', '4', '--nfe', '2',"
        f" '--device', 'cpu', '--out', {str(outs['float32'])!r}])\n"
        "sys.exit(a or b)\n")
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"mlct: note: bfloat16 needs a CPU with {cpu_features.bf16_feature()}, which this one "
        f"lacks; running float32, which is faster here"]
    np.testing.assert_array_equal(np.load(outs["bfloat16"]), np.load(outs["float32"]))
