"""What ONNX Runtime's int8 matrix product computes on an x86-64 CPU without VNNI, on any CPU.

Why: ONNX Runtime has no switch for its kernels at run time (only a build option), and its
u8 x s8 product (MatMulInteger, what dynamic quantization writes) is not the same arithmetic on
every CPU. With VNNI (vpdpbusd) every product is summed in int32: exact. With AVX2 or AVX-512
without VNNI, MLAS multiplies with vpmaddubsw, which adds each pair of neighbouring products
along K into an int16 and saturates it at +-32767: a pair of 255 x 127 products (64770) is cut
in half. ONNX Runtime's quantization guide names this ("saturation ... try reduce_range or
U8U8"). `as_non_vnni` rewrites each such product of a graph into float operators that compute
exactly that, so a test on a VNNI machine sees what an AVX2-only one computes. A u8 x u8
product (MLAS widens both to int16, no saturation) is left as it is: exact on every kernel.
"""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

INT16 = (-32768.0, 32767.0)


def as_non_vnni(model: onnx.ModelProto) -> tuple[onnx.ModelProto, int]:
    """A copy of `model` whose u8 x s8 MatMulInteger nodes (constant s8 B, zero point 0, as
    symmetric weight quantization writes them) compute vpmaddubsw's saturated pairs; and how
    many nodes were rewritten."""
    model = onnx.ModelProto.FromString(model.SerializeToString())
    graph = model.graph
    consts = {init.name: numpy_helper.to_array(init) for init in graph.initializer}
    nodes, rewritten = [], 0
    for node in graph.node:
        b = consts.get(node.input[1]) if node.op_type == "MatMulInteger" else None
        if b is None or b.dtype != np.int8 or b.ndim != 2:
            nodes.append(node)
            continue
        b_zero = consts.get(node.input[3]) if len(node.input) > 3 and node.input[3] else None
        if b_zero is not None and np.any(b_zero != 0):
            raise ValueError(f"{node.name}: an s8 B with a zero point is not what it emulates")
        nodes.extend(_saturated_product(node, b.astype(np.float64), graph, rewritten))
        rewritten += 1
    del graph.node[:]
    graph.node.extend(nodes)
    used = {name for node in graph.node for name in node.input}
    for init in [i for i in graph.initializer if i.name not in used]:
        graph.initializer.remove(init)  # the int8 weights now read as float64 constants
    return model, rewritten


def _saturated_product(node: onnx.NodeProto, b: np.ndarray, graph: onnx.GraphProto,
                       index: int) -> list[onnx.NodeProto]:
    """Nodes for int32 Y = sum_j sat16(A[2j] B[2j] + A[2j+1] B[2j+1]) - a_zero * sum_k B[k],
    A the node's u8 input, in float64 (exact for these integers)."""
    k, n = b.shape
    if k % 2:  # (MLAS pads K with a zero; no graph tested here has an odd K)
        raise ValueError(f"{node.name}: odd K {k}")
    p = f"non_vnni{index}_"
    graph.initializer.extend([
        numpy_helper.from_array(b[0::2], p + "b_even"),
        numpy_helper.from_array(b[1::2], p + "b_odd"),
        numpy_helper.from_array(b.sum(0), p + "b_sum"),
        numpy_helper.from_array(np.array([2 * k], np.int64), p + "ends"),
        numpy_helper.from_array(np.array([-1], np.int64), p + "axes"),
        numpy_helper.from_array(np.array([2], np.int64), p + "steps"),
        numpy_helper.from_array(np.array([-2], np.int64), p + "axis_k"),
        numpy_helper.from_array(np.array(INT16[0]), p + "lo"),
        numpy_helper.from_array(np.array(INT16[1]), p + "hi"),
        numpy_helper.from_array(np.array([-1], np.int64), p + "last")])
    a, a_zero = node.input[0], node.input[2] if len(node.input) > 2 else ""
    out = []
    cast = lambda src, dst, to: helper.make_node("Cast", [src], [dst], to=to)
    out.append(cast(a, p + "a", TensorProto.DOUBLE))
    for half, start in (("even", 0), ("odd", 1)):
        graph.initializer.append(numpy_helper.from_array(np.array([start], np.int64),
                                                         p + f"start_{half}"))
        out.append(helper.make_node("Slice", [p + "a", p + f"start_{half}", p + "ends",
                                              p + "axes", p + "steps"], [p + f"a_{half}"]))
        out.append(helper.make_node("Unsqueeze", [p + f"a_{half}", p + "last"],
                                    [p + f"a_{half}_col"]))
        out.append(helper.make_node("Mul", [p + f"a_{half}_col", p + f"b_{half}"],
                                    [p + f"prod_{half}"]))  # (..., M, K/2, N)
    out.append(helper.make_node("Add", [p + "prod_even", p + "prod_odd"], [p + "pairs"]))
    out.append(helper.make_node("Clip", [p + "pairs", p + "lo", p + "hi"], [p + "saturated"]))
    out.append(helper.make_node("ReduceSum", [p + "saturated", p + "axis_k"], [p + "raw"],
                                keepdims=0))
    result = p + "raw"
    if a_zero:
        out.append(cast(a_zero, p + "a_zero", TensorProto.DOUBLE))
        out.append(helper.make_node("Mul", [p + "a_zero", p + "b_sum"], [p + "zero_term"]))
        out.append(helper.make_node("Sub", [p + "raw", p + "zero_term"], [p + "centred"]))
        result = p + "centred"
    out.append(cast(result, node.output[0], TensorProto.INT32))
    return out
