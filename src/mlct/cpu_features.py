"""What this CPU's kernels can do, asked of torch itself: the precision a generator runs in.

Why: PyTorch's oneDNN kernels run bfloat16 only where the CPU has AVX-512 (BW, VL, DQ) or
AVX-NE-CONVERT on x86-64, or the BF16 extension on ARM64; elsewhere oneDNN's own ops refuse
bfloat16 ("mkldnn_convolution: bf16 path needs the cpu support ...") and the plain ATen kernels
that remain run bfloat16 products element by element. Measured with oneDNN and ATen held to
AVX2 (ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2, docs/performance.md): three 4-s motions
of the bundled model took 0.21-0.34 s in bfloat16 on those kernels against 0.05 s in float32. So
where bfloat16 has no kernels a generator runs float32, faster and exact, and says so in one
line. torch's check follows ONEDNN_MAX_CPU_ISA, so that variable makes any machine show the
fallback (tests/test_bad_inputs.py).
"""

from __future__ import annotations

import functools
import os
import platform
import sys
import warnings
from typing import Any

import torch

from mlct.devices import resolve_device
from mlct.errors import MlctError, MlctWarning

WEIGHT_DTYPES = {"float32": torch.float32, "bfloat16": torch.bfloat16}


def weight_dtype(name: str | torch.dtype) -> torch.dtype:
    """The torch dtype for a weight-precision name; ValueError naming the choices otherwise."""
    if isinstance(name, torch.dtype) and name in WEIGHT_DTYPES.values():
        return name
    if isinstance(name, str) and name in WEIGHT_DTYPES:
        return WEIGHT_DTYPES[name]
    raise ValueError(f"unknown weight dtype {name!r}; choose one of {', '.join(WEIGHT_DTYPES)}")


@functools.cache  # the CPU does not change; the layers ask on every call
def onednn_bf16() -> bool:
    """Whether oneDNN runs bfloat16 on this CPU (torch's own check, the one its ops make)."""
    try:
        return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):  # a torch without oneDNN: no bf16 kernels either
        return False


def bf16_feature() -> str:
    """The CPU feature oneDNN's bfloat16 kernels need, in words, for this architecture."""
    if platform.machine().lower() in ("arm64", "aarch64"):
        return "the BF16 extension"
    return "AVX-512 (BW, VL, DQ) or AVX-NE-CONVERT"


def kernel_dtype(dtype: Any, device: Any) -> Any:
    """`dtype` as given, or torch.float32 (with a one-line MlctWarning) where it is bfloat16 on
    a CPU whose oneDNN has no bfloat16 kernels. A dtype or device that is not one is returned
    as it is: the caller's own check says what is wrong with it."""
    try:
        if weight_dtype(dtype) != torch.bfloat16 or resolve_device(device).type != "cpu":
            return dtype
    except (ValueError, MlctError):
        return dtype
    if onednn_bf16():
        return dtype
    lacking = (f"a CPU with {bf16_feature()}, which this one lacks"
               if torch.backends.mkldnn.is_available()
               else "PyTorch's oneDNN kernels, which this build of torch lacks")
    warnings.warn(f"bfloat16 needs {lacking}; running float32, which is faster here",
                  MlctWarning, stacklevel=_caller_outside())
    return torch.float32


def _caller_outside() -> int:
    """warnings.warn's stacklevel, from kernel_dtype, of the first caller outside mlct: the
    line the notice names is the user's, however deep inside mlct it was raised."""
    root, level = os.path.dirname(os.path.abspath(__file__)), 1
    frame = sys._getframe(2)  # kernel_dtype's caller
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(root):
        frame, level = frame.f_back, level + 1
    return level + 1
