"""The denoiser's and decoder's self-attentions as ONNX Runtime's fused operators.

torch.onnx writes each of the denoiser's attentions (mlct.nn.inference.FastEncoderLayer) as
~60 standard operators: the packed q/k/v product and its bias, a Reshape to (B, S, 3, H, d), a
Transpose, a Split and three Squeezes, the two scaled products around a Softmax, a Transpose and
a Reshape back, plus the shape arithmetic feeding the Reshapes. On 6 tokens each of them costs
more to dispatch than to compute. `com.microsoft.Attention` (ONNX Runtime's contrib operator)
does the same from the block's input, the packed weight (input width, 3 x width: the q, k and v
columns, heads contiguous in each, as the Reshape splits them) and the bias, with the default
scale 1 / sqrt(d); the Reshape back to (B, S, width) is its output. The bundled model's one-step
denoiser graph goes from 406 to 226 operators and 383 to 340 us on one thread; the outputs
agree to 5e-6, the 5-step sampler graph's latents to the bit (docs/performance.md).

The autoencoder's attentions over frames carry a key padding mask (True = a padded frame):
torch.onnx writes it as Where(Not(pad[:, None, None, :]), 0, -inf) added to the scores, and a
guard that turns a Softmax row of NaN (every key padded) into zeros. With `padded=True` such a
block becomes the same Attention node with a fifth input, the mask as ONNX Runtime reads it
((B, S) int32, 1 = attend; one Not and one Cast, shared by the blocks). ONNX Runtime masks with
-10000 rather than -inf, which is the same after the Softmax unless a whole row is masked, so
`padded` is for graphs where that cannot happen: the autoencoder's decoder keeps its latent
tokens in front of every row's keys (nn/autoencoder.py). The paper-size decoder (7 blocks over
199 tokens) takes 17 ms instead of 25 on 2 threads, its features within 1e-6.

After a q/k/v product in blockwise int8 (MatMulNBits, `mlct convert --onnx --int8`) the Attention
operator cannot take the weight, so the product stays and the rest becomes a Split into q, k
and v and `com.microsoft.MultiHeadAttention` (the bias added inside): the same arithmetic after
the product (1e-5 with float arithmetic in the product; docs/performance.md).

Only ONNX Runtime runs the fused operator, so the rewrite is applied in memory to the sampler
graph and the decoder's session of the onnx backend (onnx_sampler.sampler_model,
networks.OnnxDecoder), never to the graphs on disk, which the static site's
onnxruntime-web and other runtimes read. A block whose nodes are not exactly one of the
patterns above (another mask, another exporter's names) is left as it is.
"""

from __future__ import annotations

from typing import Any

# What may lie between a block's q/k/v product and its output Reshape: the pattern, and the
# shape arithmetic torch.onnx writes for its Reshapes and the scale. A Where, an Add of a
# mask or any other operator there means a different attention: the block is not fused.
PATTERN_OPS = frozenset({
    "MatMul", "Add", "Reshape", "Transpose", "Split", "Squeeze", "Mul", "Softmax",
    "Cast", "Constant", "Shape", "Gather", "Unsqueeze", "Concat", "Slice", "Div", "Sqrt"})
# A block's q/k/v product: float32 (MatMul), or int8 by blocks (MatMulNBits, onnx_compact's
# quantize_blockwise_int8 names it .../MatMul_Q8)
QKV_PRODUCTS = ("/qkv/MatMul", "/qkv/MatMul_Q8")
# ... and what a padded block adds: the mask's Not and Where, the NaN guard's IsNaN and Where
PADDED_OPS = PATTERN_OPS | {"Not", "Where", "IsNaN"}
MS_DOMAIN = "com.microsoft"


def fuse_attention(model: Any, heads: int, padded: bool = False) -> int:
    """Rewrite model (an onnx.ModelProto of denoiser.onnx or decoder.onnx) in place: each
    self-attention block named `<block>/qkv/MatMul`, `<block>/qkv/Add` ... `<block>/Reshape_1`
    by torch.onnx becomes one com.microsoft Attention node of `heads` heads (after an int8
    product `<block>/qkv/MatMul_Q8`: the product, a Split and a MultiHeadAttention node).
    padded: blocks with a key padding mask are fused too, with the mask (only where no row can
    be all padding: above). Returns how many blocks were fused."""
    import numpy as np
    from onnx import TensorProto, helper, numpy_helper

    graph = model.graph
    producer = {out: node for node in graph.node for out in node.output}
    by_name = {node.name: node for node in graph.node}
    constants = {tensor.name for tensor in graph.initializer}
    constants |= {node.output[0] for node in graph.node  # torch.onnx shares equal weights
                  if node.op_type == "Identity" and node.input[0] in constants}  # (zero biases)
    masks: dict[str, str] = {}  # pad mask -> its int32 form, made once
    fused = 0
    products = [node for node in graph.node if node.name.endswith(QKV_PRODUCTS)]
    for product in products:
        block = product.name.rsplit("/qkv/", 1)[0]
        bias_add, output = by_name.get(block + "/qkv/Add"), by_name.get(block + "/Reshape_1")
        if bias_add is None or output is None or product.output[0] not in bias_add.input:
            continue
        (bias,) = [name for name in bias_add.input if name != product.output[0]]
        pad = _padding_mask(block, graph, producer) if padded else None
        if not _is_plain_attention(output, product, producer,
                                   constants if pad is None else constants | {pad},
                                   PATTERN_OPS if pad is None else PADDED_OPS):
            continue
        if pad is not None and pad not in masks:  # (B, S) bool, True = pad -> int32, 1 = attend
            masks[pad] = f"{pad}/attend_int32"
            graph.node.extend([
                helper.make_node("Not", [pad], [f"{pad}/attend"]),
                helper.make_node("Cast", [f"{pad}/attend"], [masks[pad]], to=TensorProto.INT32)])
        mask = [] if pad is None else [masks[pad]]
        if product.op_type == "MatMul":  # the weight is a float matrix: Attention reads it
            fused_nodes = [helper.make_node(
                "Attention", [product.input[0], product.input[1], bias, *mask],
                [output.output[0]], name=block + "/Attention", domain=MS_DOMAIN,
                num_heads=heads)]
        else:  # blockwise int8 (MatMulNBits): keep the product, fuse what follows it
            width = next(a.i for a in product.attribute if a.name == "N") // 3
            sizes = block + "/qkv_sizes"
            graph.initializer.append(numpy_helper.from_array(
                np.array([width] * 3, np.int64), sizes))
            q, k, v = (f"{block}/{name}" for name in "qkv")
            fused_nodes = [
                helper.make_node("Split", [product.output[0], sizes], [q, k, v],
                                 name=block + "/qkv_split", axis=-1),
                helper.make_node("MultiHeadAttention", [q, k, v, bias, *mask],
                                 [output.output[0]], name=block + "/Attention",
                                 domain=MS_DOMAIN, num_heads=heads)]
        at = list(graph.node).index(output)
        graph.node.remove(output)
        for node in reversed(fused_nodes):
            graph.node.insert(at, node)
        fused += 1
    if fused:
        if masks:  # the masks' nodes were appended: put every node after what it reads
            _sort_topologically(graph)
        _drop_unused_nodes(graph)
        if not any(opset.domain == MS_DOMAIN for opset in model.opset_import):
            model.opset_import.append(helper.make_opsetid(MS_DOMAIN, 1))
    return fused


def _padding_mask(block: str, graph: Any, producer: dict[str, Any]) -> str | None:
    """The (B, S) key padding mask (True = pad) that block's Where(Not(pad[:, None, None, :]),
    0, -inf) reads, as torch.onnx writes a masked attention; None if the block has no such
    Where."""
    from onnx import numpy_helper

    def constant(value: str) -> float | None:
        node = producer.get(value)
        if node is None or node.op_type != "Constant" or not node.attribute:
            return None
        array = numpy_helper.to_array(node.attribute[0].t)
        return float(array.reshape(-1)[0]) if array.size == 1 else None

    for where in graph.node:
        if where.op_type != "Where" or not where.name.startswith(block + "/"):
            continue
        keep, yes, no = where.input
        if constant(yes) != 0.0 or constant(no) != float("-inf"):
            continue
        node = producer.get(keep)
        if node is None or node.op_type != "Not":
            continue
        value = node.input[0]
        for _ in range(2):  # pad[:, None, None, :]: two Unsqueezes
            node = producer.get(value)
            if node is None or node.op_type != "Unsqueeze":
                return None
            value = node.input[0]
        return value
    return None


def _is_plain_attention(output: Any, product: Any, producer: dict[str, Any],
                        constants: set[str], ops: frozenset[str]) -> bool:
    """Does everything output (the Reshape back) depends on, back to the q/k/v product's
    input, consist of `ops` with exactly one Softmax, pass through the product, and read no
    other value of the graph than that input (or what it is a Cast of) and constants (the pad
    mask, for a padded block)? A graph input reached otherwise would be a mask. Shapes end the
    search: they feed the Reshapes and the scale, which the fused operator does itself."""
    stops = {product.input[0]}
    node = producer.get(product.input[0])
    while node is not None and node.op_type == "Cast":  # the shape arithmetic reads the
        stops.add(node.input[0])                        # block's input before its Cast
        node = producer.get(node.input[0])
    seen: set[str] = set()
    softmaxes, through_product = 0, False
    stack = list(output.input)
    while stack:
        value = stack.pop()
        if not value or value in stops or value in constants or value in seen:
            continue
        seen.add(value)
        node = producer.get(value)
        if node is product:
            through_product = True
            continue
        if node is None or node.op_type not in ops:
            return False
        softmaxes += node.op_type == "Softmax"
        if node.op_type == "Shape":  # reads a shape, not values: torch.onnx may take it from
            continue                 # another block's input of the same shape
        stack.extend(node.input)
    return softmaxes == 1 and through_product


def _drop_unused_nodes(graph: Any) -> None:
    """Remove nodes none of whose outputs is read by another node or is a graph output."""
    outputs = {value.name for value in graph.output}
    while True:
        read = {name for node in graph.node for name in node.input} | outputs
        unused = [node for node in graph.node if not any(out in read for out in node.output)]
        if not unused:
            return
        for node in unused:
            graph.node.remove(node)


def _sort_topologically(graph: Any) -> None:
    """Reorder graph's nodes so that each comes after the producers of what it reads."""
    ready = {value.name for value in graph.input} | {t.name for t in graph.initializer} | {""}
    order, waiting = [], list(graph.node)
    while waiting:
        still = []
        for node in waiting:
            if all(name in ready for name in node.input):
                order.append(node)
                ready.update(node.output)
            else:
                still.append(node)
        if len(still) == len(waiting):
            raise ValueError("the graph has a cycle or reads a value nothing produces")
        waiting = still
    del graph.node[:]
    graph.node.extend(order)
