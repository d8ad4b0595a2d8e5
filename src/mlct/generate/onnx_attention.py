"""The denoiser's self-attention as ONNX Runtime's fused Attention operator (issue 17).

torch.onnx writes each of the denoiser's attentions (mlct.nn.inference.FastEncoderLayer) as
~60 standard operators: the packed q/k/v product and its bias, a Reshape to (B, S, 3, H, d), a
Transpose, a Split and three Squeezes, the two scaled products around a Softmax, a Transpose and
a Reshape back, plus the shape arithmetic feeding the Reshapes. On 6 tokens each of them costs
more to dispatch than to compute. `com.microsoft.Attention` (ONNX Runtime's contrib operator)
does the same from the block's input, the packed weight (input width, 3 x width: the q, k and v
columns, heads contiguous in each, as the Reshape splits them) and the bias, with the default
scale 1 / sqrt(d); the Reshape back to (B, S, width) is its output. The bundled model's one-step
denoiser graph goes from 406 to 226 operators and 383 to 340 us on one thread; the outputs
agree to 5e-6, the 5-step sampler graph's latents to the bit (docs/performance.md, "Spinning
while the machine is idle, the attention fused").

Only ONNX Runtime runs the fused operator, so the rewrite is applied in memory to the sampler
graph of the onnx backend (onnx_sampler.sampler_model), never to denoiser.onnx on disk, which
the static site's onnxruntime-web and other runtimes read. A block whose nodes are not exactly
the unmasked pattern above (a mask, another exporter's names) is left as it is.
"""

from __future__ import annotations

from typing import Any

# What may lie between a block's q/k/v product and its output Reshape: the pattern, and the
# shape arithmetic torch.onnx writes for its Reshapes and the scale. A Where, an Add of a
# mask or any other operator there means a different attention: the block is not fused.
PATTERN_OPS = frozenset({
    "MatMul", "Add", "Reshape", "Transpose", "Split", "Squeeze", "Mul", "Softmax",
    "Cast", "Constant", "Shape", "Gather", "Unsqueeze", "Concat", "Slice", "Div", "Sqrt"})
MS_DOMAIN = "com.microsoft"


def fuse_attention(model: Any, heads: int) -> int:
    """Rewrite model (an onnx.ModelProto of denoiser.onnx) in place: each self-attention block
    named `<block>/qkv/MatMul`, `<block>/qkv/Add` ... `<block>/Reshape_1` by torch.onnx becomes
    one com.microsoft Attention node of `heads` heads. Returns how many blocks were fused."""
    from onnx import helper

    graph = model.graph
    producer = {out: node for node in graph.node for out in node.output}
    by_name = {node.name: node for node in graph.node}
    constants = {tensor.name for tensor in graph.initializer}
    fused = 0
    for product in [n for n in graph.node if n.name.endswith("/qkv/MatMul")]:
        block = product.name[: -len("/qkv/MatMul")]
        bias_add, output = by_name.get(block + "/qkv/Add"), by_name.get(block + "/Reshape_1")
        if bias_add is None or output is None or product.output[0] not in bias_add.input:
            continue
        (bias,) = [name for name in bias_add.input if name != product.output[0]]
        if not _is_plain_attention(output, product, producer, constants):
            continue
        attention = helper.make_node(
            "Attention", [product.input[0], product.input[1], bias], [output.output[0]],
            name=block + "/Attention", domain=MS_DOMAIN, num_heads=heads)
        nodes = list(graph.node)
        graph.node.insert(nodes.index(output), attention)
        graph.node.remove(output)
        fused += 1
    if fused:
        _drop_unused_nodes(graph)
        if not any(opset.domain == MS_DOMAIN for opset in model.opset_import):
            model.opset_import.append(helper.make_opsetid(MS_DOMAIN, 1))
    return fused


def _is_plain_attention(output: Any, product: Any, producer: dict[str, Any],
                        constants: set[str]) -> bool:
    """Does everything output (the Reshape back) depends on, back to the q/k/v product's
    input, consist of PATTERN_OPS with exactly one Softmax, pass through the product, and read
    no other value of the graph than that input (or what it is a Cast of) and constants? A
    graph input reached otherwise would be a mask."""
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
        if node is None or node.op_type not in PATTERN_OPS:
            return False
        softmaxes += node.op_type == "Softmax"
        if node is product:
            through_product = True
            continue
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
