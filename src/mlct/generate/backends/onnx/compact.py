"""Smaller ONNX graphs for the web: weights stored in float16 where that is exact, and the text
encoder quantized to int8. Graph-to-graph rewrites with the onnx package and ONNX Runtime's
quantization tools (no torch.onnx, no sessions: those stay in mlct.onnx_io).

Why: a static site (`mlct export-web`) downloads every graph; float32 graphs of the bundled model
are 20 MB (denoiser), 4 MB (decoder) and 90 MB (MiniLM).
- The bundle stores its weights in float16 (model.safetensors), so its float32 graphs hold
  float16 values: stored as float16 with a Cast to float32 in front, each weight is the same
  number and the graph computes the same thing (ONNX Runtime folds the casts at load), at half
  the size. Weights that float16 would change (none in the bundled model) stay float32.
- MiniLM's float32 weights do not fit float16 exactly and are 90 MB; int8 makes them 23 MB.
  Two ways (docs/web.md has the figures): `quantize_int8`, ONNX Runtime's dynamic quantization
  of the matrix products and the word-embedding table (int8 weights per channel, activations
  quantized at run time, int8 arithmetic): the fastest, sentence vectors within a cosine of
  0.99 of the float32 ones; or `quantize_int8_weights`, int8 storage of the matrix products'
  weights dequantized to float32 inside the graph: cosine 0.999, but ONNX Runtime Web
  dequantizes on every run (~8x slower in the page). The Python reference of the site
  (tests/test_web_static_e2e.py) runs the same quantized graph as the page.

And one for the CPU backend: `quantize_blockwise_int8`, the denoiser of `onnx-int8` (mlct
convert --onnx --int8), int8 with a scale per 32 weights (ONNX Runtime's MatMulNBits).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from mlct.errors import MlctError
from mlct.generate.backends.onnx.int8_pairs import make_pairs_safe

MIN_FP16_SIZE = 1024  # smaller initializers (biases of norms, shapes) stay as they are
QUANTIZED_OPS = ("MatMul", "Gather")  # the matrix products and the word-embedding table


def require_onnx():
    """The onnx module; MlctError saying how to install it when it is missing."""
    try:
        import onnx
    except ImportError:
        raise MlctError("writing ONNX graphs needs the onnx package, which is not installed: "
                        "pip install onnx==1.23.2") from None
    return onnx


def float16_storage(src: str | os.PathLike, dst: str | os.PathLike) -> int:
    """Copy graph src to dst with each float32 weight that float16 holds exactly stored as
    float16 and cast back at the graph's start; returns how many weights were converted."""
    onnx = require_onnx()
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load(str(src))
    graph = model.graph
    casts, halves = [], []
    for init in list(graph.initializer):
        if init.data_type != TensorProto.FLOAT:
            continue
        weight = numpy_helper.to_array(init)
        half = weight.astype(np.float16)
        if weight.size < MIN_FP16_SIZE or not np.array_equal(half.astype(np.float32), weight):
            continue  # float16 would change it: kept exact
        graph.initializer.remove(init)
        halves.append(numpy_helper.from_array(half, f"{init.name}__float16"))
        casts.append(helper.make_node("Cast", [f"{init.name}__float16"], [init.name],
                                      to=TensorProto.FLOAT, name=f"{init.name}__cast"))
    graph.initializer.extend(halves)
    nodes = list(graph.node)
    del graph.node[:]
    graph.node.extend(casts + nodes)  # before every use: the graph stays topologically sorted
    onnx.checker.check_model(model)
    onnx.save(model, str(dst))
    return len(casts)


def quantize_int8(src: str | os.PathLike, dst: str | os.PathLike,
                  op_types: tuple[str, ...] = QUANTIZED_OPS) -> Path:
    """ONNX Runtime's dynamic int8 quantization (weights per channel, symmetric; activations
    at run time) of src's operators of op_types, written to dst; each column's scale such that
    every CPU's int8 kernels compute the same sums (backends/onnx/int8_pairs.py)."""
    onnx = require_onnx()
    try:
        from onnxruntime.quantization import QuantType, quantize_dynamic
    except ImportError:
        raise MlctError("int8 quantization needs ONNX Runtime, which is not "
                        "installed: pip install onnxruntime==1.32.0") from None
    root = logging.getLogger()  # it advises pre-processing on the root logger, every time
    level = root.level
    root.setLevel(logging.ERROR)
    try:
        with tempfile.TemporaryDirectory() as tmp:  # its notes (augmented models) stay out
            quantize_dynamic(str(src), str(Path(tmp) / "quantized.onnx"),
                             op_types_to_quantize=list(op_types), per_channel=True,
                             weight_type=QuantType.QInt8)
            if {"MatMul", "Gemm"} & set(op_types):  # (a Gather's int8 is a lookup: exact)
                model = onnx.load(str(Path(tmp) / "quantized.onnx"))
                if make_pairs_safe(model, onnx.load(str(src))):
                    onnx.save(model, str(Path(tmp) / "quantized.onnx"))
            shutil.move(str(Path(tmp) / "quantized.onnx"), str(dst))
    finally:
        root.setLevel(level)
    return Path(dst)


INT8_BLOCK = 32  # weights per scale along the reduced axis (MatMulNBits' block_size)
# Products with fewer weights stay float32: their bytes cost nothing, and in the denoiser they
# are the latent's way in and out (in_proj 64 x 256, the head's 256 x 64 and 64 x 64), where
# int8's error reaches the next step whole: kept float32, the joints move 3.1 mm from
# float32's instead of 7.7 (40 test captions; docs/performance.md).
MIN_INT8_WEIGHTS = 32768


def quantize_blockwise_int8(src: str | os.PathLike, dst: str | os.PathLike,
                            block_size: int = INT8_BLOCK) -> int:
    """src's matrix products with a constant weight as ONNX Runtime's MatMulNBits, 8 bits: one
    float32 scale per `block_size` weights of a column (not per column, as `quantize_int8`), the
    activations quantized per block at run time too (accuracy_level 4: int8 arithmetic, the
    CPU's VNNI), but for products of fewer than MIN_INT8_WEIGHTS weights; written to dst.
    Returns how many products were quantized.

    Why blocks: the sampler feeds each step's output into the next, so a product's error grows
    over 5 steps; with per-block scales the joints end 3.6x closer to float32's than with
    per-column dynamic quantization, which is 15 % faster (docs/performance.md)."""
    onnx = require_onnx()
    try:
        from onnxruntime.quantization.matmul_nbits_quantizer import (
            DefaultWeightOnlyQuantConfig, MatMulNBitsQuantizer)
    except ImportError as err:
        raise MlctError(f"blockwise int8 needs ONNX Runtime's quantization tools ({err}): "
                        "pip install 'mlct[train]'") from None
    config = DefaultWeightOnlyQuantConfig(block_size=block_size, is_symmetric=True,
                                          accuracy_level=4, bits=8)
    model = onnx.load(str(src))
    sizes = {init.name: int(np.prod(init.dims)) for init in model.graph.initializer}
    small = [node.name for node in model.graph.node if node.op_type == "MatMul"
             and sizes.get(node.input[1], MIN_INT8_WEIGHTS) < MIN_INT8_WEIGHTS]
    quiet = logging.getLogger("onnxruntime.quantization.matmul_nbits_quantizer")
    level = quiet.level
    quiet.setLevel(logging.WARNING)  # it logs every node it looks at
    try:
        quantizer = MatMulNBitsQuantizer(model, algo_config=config, nodes_to_exclude=small)
        quantizer.process()
    finally:
        quiet.setLevel(level)
    model = quantizer.model.model
    onnx.save(model, str(dst))
    return sum(node.op_type == "MatMulNBits" for node in model.graph.node)


def quantize_int8_weights(src: str | os.PathLike, dst: str | os.PathLike) -> int:
    """src's word-embedding table as ONNX Runtime's int8 lookup (quantize_int8 on Gather) and
    each matrix product's 2-d weight stored as int8 with a float32 scale per output column,
    DequantizeLinear -> float32 in the graph (weight-only: the arithmetic stays float32);
    written to dst. Returns how many weights were stored as int8."""
    onnx = require_onnx()
    from onnx import helper, numpy_helper

    with tempfile.TemporaryDirectory() as tmp:
        quantize_int8(src, Path(tmp) / "gather.onnx", ("Gather",))
        model = onnx.load(str(Path(tmp) / "gather.onnx"))
    graph = model.graph
    weights = {init.name: init for init in graph.initializer}
    users: dict[str, set[str]] = {}
    for node in graph.node:
        for name in node.input:
            users.setdefault(name, set()).add(node.op_type)
    dequantize = []
    for node in graph.node:
        name = node.input[1] if node.op_type == "MatMul" else None
        if name not in weights or users[name] != {"MatMul"}:
            continue
        weight = numpy_helper.to_array(weights.pop(name))
        if weight.ndim != 2 or weight.dtype != np.float32:
            continue
        scale = np.abs(weight).max(axis=0) / 127.0  # (N,): one per output column
        scale[scale == 0] = 1.0
        q = np.clip(np.round(weight / scale), -127, 127).astype(np.int8)
        graph.initializer.remove(next(i for i in graph.initializer if i.name == name))
        graph.initializer.extend([numpy_helper.from_array(q, f"{name}__int8"),
                                  numpy_helper.from_array(scale.astype(np.float32),
                                                          f"{name}__scale")])
        dequantize.append(helper.make_node("DequantizeLinear", [f"{name}__int8",
                                                                f"{name}__scale"],
                                           [name], axis=1, name=f"{name}__dequantize"))
    nodes = list(graph.node)
    del graph.node[:]
    graph.node.extend(dequantize + nodes)
    onnx.checker.check_model(model)
    onnx.save(model, str(dst))
    return len(dequantize)
