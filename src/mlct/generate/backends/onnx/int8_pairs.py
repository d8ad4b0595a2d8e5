"""int8 weights whose products sum the same on every CPU's int8 kernels.

Why: ONNX Runtime's dynamic quantization multiplies uint8 activations by int8 weights
(MatMulInteger), and its x86-64 kernels do not all sum alike. With VNNI every product is added in
int32; on AVX2, or AVX-512 without VNNI, vpmaddubsw first adds each pair of neighbouring
products along K into an int16 that saturates at 32767 (ONNX Runtime's quantization guide:
"saturation ... try reduce_range or U8U8"). A small test network came out 1 % off float32 on a
VNNI CPU and 20 % off on an AVX2-only one. The guide's two ways out both cost: 7-bit weights
(reduce_range) moved MiniLM's sentence vectors to a median cosine of 0.958 with float32's
(0.986 before), uint8 weights (U8U8) ran 1.75x slower on a VNNI CPU (14.1 -> 24.7 ms a prompt;
bench/int8_across_kernels.py).

Here each weight column keeps 8 bits but its scale is set so that no two neighbouring weights
of it (rows 2j and 2j + 1, vpmaddubsw's pairs) sum to more than 128 in magnitude after
rounding: 255 x 128 = 32640 fits an int16, so no kernel saturates and every one computes the
exact int32 sums VNNI does. The scale grows only in a column whose largest weights sit side by
side: MiniLM's vectors are at a median cosine of 0.9856 (min 0.9785) with float32's on every
kernel, against 0.9863 (min 0.9814) with VNNI and 0.9762 (min 0.9684) without it before, at the
int8 kernels' speed (16.5 ms a prompt; 62 benchmark prompts, bench/int8_across_kernels.py).
"""

from __future__ import annotations

import numpy as np

PAIR_LIMIT = 127  # |w_2j| + |w_2j+1| <= 127 scales: two roundings add at most 1, to 128
QUANTIZED_SUFFIX = "_quantized"  # quantize_dynamic's names: X_quantized, X_scale, X_zero_point


def pair_safe_scales(weight: np.ndarray) -> np.ndarray:
    """(K, N) float weights -> (N,) scales: at least max |w| / 127 (symmetric int8), and large
    enough that |w_2j| + |w_2j+1| <= 127 scales in every column."""
    w = np.abs(weight.astype(np.float64))
    if len(w) % 2:
        w = np.concatenate([w, np.zeros((1, w.shape[1]))])  # MLAS pads K with a zero
    pairs = w[0::2] + w[1::2]
    scale = np.maximum(w.max(0) / 127.0, pairs.max(0) / PAIR_LIMIT)
    scale[scale == 0] = 1.0
    return scale.astype(np.float32)


def max_pair(q: np.ndarray) -> int:
    """The largest |q_2j| + |q_2j+1| of a (K, N) int8 matrix: at most 128 never saturates."""
    a = np.abs(q.astype(np.int32))
    if len(a) % 2:
        a = np.concatenate([a, np.zeros((1, a.shape[1]), np.int32)])
    return int((a[0::2] + a[1::2]).max()) if a.size else 0


def make_pairs_safe(model, float_model) -> int:
    """Rewrite, in place, the int8 weights (and their scales) of `model`'s MatMulInteger nodes,
    quantized per column with zero points 0 from `float_model`'s float32 weights, so that no
    neighbouring pair saturates an int16; returns how many weights were rewritten."""
    from onnx import numpy_helper

    inits = {init.name: init for init in model.graph.initializer}
    floats = {init.name: init for init in float_model.graph.initializer}
    rewritten = 0
    for node in model.graph.node:
        if node.op_type != "MatMulInteger" or node.input[1] not in inits:
            continue
        name = node.input[1]
        q = numpy_helper.to_array(inits[name])
        base = name[:-len(QUANTIZED_SUFFIX)] if name.endswith(QUANTIZED_SUFFIX) else None
        scale_init = inits.get(f"{base}_scale")
        zero = inits.get(f"{base}_zero_point")
        if (q.dtype != np.int8 or q.ndim != 2 or scale_init is None
                or (zero is not None and np.any(numpy_helper.to_array(zero) != 0))):
            continue
        weight = _float_weight(base, floats, q, numpy_helper.to_array(scale_init))
        scale = pair_safe_scales(weight)
        new_q = np.clip(np.round(weight / scale), -127, 127).astype(np.int8)
        inits[name].CopyFrom(numpy_helper.from_array(new_q, name))
        scale_init.CopyFrom(numpy_helper.from_array(scale.reshape(
            numpy_helper.to_array(scale_init).shape), scale_init.name))
        rewritten += 1
    return rewritten


def _float_weight(base: str, floats: dict, q: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The (K, N) float32 weight that `base`'s int8 one was made of: the float graph's own
    (quantize_dynamic names a Gemm's transposed copy X_Transposed), else q x scale."""
    from onnx import numpy_helper

    if base in floats:
        weight = numpy_helper.to_array(floats[base])
    elif base.endswith("_Transposed") and base[:-len("_Transposed")] in floats:
        weight = numpy_helper.to_array(floats[base[:-len("_Transposed")]]).T
    else:
        weight = q.astype(np.float32) * scale
    if weight.shape != q.shape:
        raise ValueError(f"{base}: float weight {weight.shape} is not the int8 one's {q.shape}")
    return weight.astype(np.float32)
