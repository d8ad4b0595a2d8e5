"""Why the static site's text encoder is not 4-bit: MiniLM's matrix products and word-embedding
table stored as 4-bit integers in blocks with one scale each, in ONNX Runtime's own operators for
that (com.microsoft MatMulNBits and GatherBlockQuantized, both in onnxruntime-web's WASM build),
against the float32 graph and the site's int8 one.

    python bench/web_int4.py          # about a minute

Prints each variant's size and the cosine of its sentence vectors with the float32 ones over the
benchmark's 62 prompts (bench/data/quality_prompts.json), and the same for the side-contrasted
vectors (text/sides.py: e + 4 (e - e(mirror))) of the prompts that name a side. docs/web.md has
the figures: 4 bits halve the encoder (23 -> 14 MB) but move the sentence vectors far more than
int8 does, so `mlct export-web` stores its graphs gzipped instead (serve/site/pack.py).

Format (ONNX Runtime's contrib operator specification): a block holds `block` consecutive
values along the reduced axis (a matrix product's K, an embedding row's features); each value
is a signed 4-bit q in [-8, 7] stored as q + 8 (the operators' default zero point), two to a
byte, the first in the low nibble; the block's value is scale * q, the scale the one of a few
candidates (absmax / 7 ... absmax / 8) with the least squared error. Written with numpy (ONNX
Runtime's own 4-bit quantizer needs the onnx-ir package and rewrote this graph to an opset
whose ReduceL2 it then failed on).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from mlct.errors import MlctError
from mlct.generate.onnx_compact import quantize_int8, require_onnx

BLOCK = 32  # values per scale: ONNX Runtime's usual 4-bit block (16, 32, 64, 128 allowed)
EMBEDDING_BLOCK = 32
MS_DOMAIN = "com.microsoft"
_DIVISORS = (7.0, 7.25, 7.5, 7.75, 8.0)  # candidate absmax / scale ratios


def block_quantize(weight: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """(R, K) float -> (R, K) int8 in [-8, 7] and (R, K / block) float32 scales, blocks along
    the last axis, each block's scale the candidate with the least squared error."""
    rows, size = weight.shape
    if size % block:
        raise MlctError(f"4-bit blocks of {block} do not divide a row of {size} values")
    w = weight.astype(np.float64).reshape(rows, size // block, block)
    amax = np.abs(w).max(-1, keepdims=True)
    best_q = best_s = best_err = None
    for divisor in _DIVISORS:
        scale = np.where(amax > 0, amax / divisor, 1.0)
        q = np.clip(np.round(w / scale), -8, 7)
        err = ((q * scale - w) ** 2).sum(-1, keepdims=True)
        if best_err is None:
            best_q, best_s, best_err = q, scale, err
        else:
            better = err < best_err
            best_q = np.where(better, q, best_q)
            best_s = np.where(better, scale, best_s)
            best_err = np.minimum(err, best_err)
    return (best_q.reshape(rows, size).astype(np.int8),
            best_s[..., 0].astype(np.float32))


def pack_int4(q: np.ndarray) -> np.ndarray:
    """(..., K) int8 in [-8, 7], K even -> (..., K / 2) uint8: q + 8, two a byte, low first."""
    u = (q.astype(np.int16) + 8).astype(np.uint8)
    return (u[..., 0::2] | (u[..., 1::2] << 4)).astype(np.uint8)


def dequantize_int4(q: np.ndarray, scales: np.ndarray, block: int) -> np.ndarray:
    """The float32 values of block_quantize's output (for tests and measurements)."""
    rows, size = q.shape
    return (q.reshape(rows, size // block, block) * scales[..., None]).reshape(rows, size) \
        .astype(np.float32)


def quantize_int4(src: str | os.PathLike, dst: str | os.PathLike, block: int = BLOCK,
                  embedding_block: int = EMBEDDING_BLOCK,
                  embedding: str | None = "word_embeddings",
                  matmuls: bool = True) -> dict[str, int]:
    """Copy graph src to dst with every MatMul by a constant (K, N) float32 matrix as a 4-bit
    MatMulNBits and the Gather from the constant table whose name contains `embedding` as a
    4-bit GatherBlockQuantized (float16 scales, cast to float32 after the gather). Returns how
    many of each were rewritten."""
    onnx = require_onnx()
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load(str(src))
    graph = model.graph
    inits = {init.name: init for init in graph.initializer}
    uses: dict[str, int] = {}
    for node in graph.node:
        for name in node.input:
            uses[name] = uses.get(name, 0) + 1
    counts = {"MatMulNBits": 0, "GatherBlockQuantized": 0}
    drop: set[str] = set()
    new_nodes, new_inits = [], []
    for node in graph.node:
        weight = node.input[1] if node.op_type == "MatMul" else (
            node.input[0] if node.op_type == "Gather" else None)
        init = inits.get(weight)
        if (init is None or init.data_type != TensorProto.FLOAT or len(init.dims) != 2
                or uses[weight] != 1):
            new_nodes.append(node)
            continue
        w = numpy_helper.to_array(init)
        if node.op_type == "MatMul" and matmuls and w.shape[0] % block == 0:
            k, n = w.shape
            q, scales = block_quantize(w.T, block)  # MatMulNBits: (N, K / block, block / 2)
            packed = pack_int4(q).reshape(n, k // block, block // 2)
            new_inits += [numpy_helper.from_array(packed, f"{weight}__q4"),
                          numpy_helper.from_array(scales.reshape(-1), f"{weight}__scales")]
            new_nodes.append(helper.make_node(
                "MatMulNBits", [node.input[0], f"{weight}__q4", f"{weight}__scales"],
                list(node.output), name=f"{node.name}__q4", domain=MS_DOMAIN,
                K=k, N=n, bits=4, block_size=block))
            counts["MatMulNBits"] += 1
        elif (node.op_type == "Gather" and embedding and embedding in weight
              and w.shape[1] % embedding_block == 0
              and all(a.name != "axis" or a.i == 0 for a in node.attribute)):
            q, scales = block_quantize(w, embedding_block)
            half = f"{node.output[0]}__float16"
            new_inits += [numpy_helper.from_array(pack_int4(q), f"{weight}__q4"),
                          numpy_helper.from_array(scales.astype(np.float16),
                                                  f"{weight}__scales")]
            new_nodes += [helper.make_node(
                "GatherBlockQuantized", [f"{weight}__q4", node.input[1], f"{weight}__scales"],
                [half], name=f"{node.name}__q4", domain=MS_DOMAIN, bits=4,
                block_size=embedding_block, gather_axis=0, quantize_axis=1),
                helper.make_node("Cast", [half], list(node.output), to=TensorProto.FLOAT,
                                 name=f"{node.name}__cast")]
            counts["GatherBlockQuantized"] += 1
        else:
            new_nodes.append(node)
            continue
        drop.add(weight)
    kept = [init for init in graph.initializer if init.name not in drop]
    del graph.initializer[:]
    graph.initializer.extend(kept + new_inits)
    del graph.node[:]
    graph.node.extend(new_nodes)
    if not any(op.domain == MS_DOMAIN for op in model.opset_import):
        model.opset_import.append(helper.make_opsetid(MS_DOMAIN, 1))
    onnx.save(model, str(Path(dst)))
    return counts


PROMPTS = Path(__file__).resolve().parent / "data" / "quality_prompts.json"


def main() -> None:
    import onnxruntime as ort
    from tokenizers import Tokenizer

    from mlct.generate.onnx_bundle import write_onnx_graphs
    from mlct.generate.pipeline import bundled_model_dir
    from mlct.text.encoders import bundled_minilm_path
    from mlct.text.sides import SIDE_CONTRAST, mirror_sides

    data = json.loads(PROMPTS.read_text())
    texts = [item["text"] for key in ("paraphrases", "two_actions") for item in data[key]]
    sided = [t for t in texts if mirror_sides(t) != t]
    tokenizer = Tokenizer.from_file(str(bundled_minilm_path() / "tokenizer.json"))

    def vectors(path: Path, items: list[str]) -> np.ndarray:
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        sess = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        out = []
        for text in items:
            ids = np.array([tokenizer.encode(text).ids], dtype=np.int64)
            out.append(sess.run(["embedding"], {"ids": ids, "mask": np.ones_like(ids)})[0][0])
        return np.array(out, dtype=np.float64)

    def contrasted(path: Path) -> np.ndarray:
        e, m = vectors(path, sided), vectors(path, [mirror_sides(t) for t in sided])
        return e + SIDE_CONTRAST * (e - m)

    def cosine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a * b).sum(1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        reference = write_onnx_graphs(bundled_model_dir(), tmp) / "text_encoder.onnx"
        variants = {"int8 (the site's)": tmp / "int8.onnx", "4-bit, block 32": tmp / "q4.onnx",
                    "4-bit, block 16": tmp / "q4b16.onnx",
                    "4-bit matrix products only (block 32)": tmp / "q4mm.onnx",
                    "4-bit embedding table only (block 32)": tmp / "q4emb.onnx"}
        quantize_int8(reference, variants["int8 (the site's)"])
        quantize_int4(reference, variants["4-bit, block 32"])
        quantize_int4(reference, variants["4-bit, block 16"], block=16, embedding_block=16)
        quantize_int4(reference, variants["4-bit matrix products only (block 32)"],
                      embedding=None)
        quantize_int4(reference, variants["4-bit embedding table only (block 32)"],
                      matmuls=False)
        ref, ref_sided = vectors(reference, texts), contrasted(reference)
        print(f"{len(texts)} prompts, {len(sided)} of them naming a side")
        for name, path in variants.items():
            cos, cos_sided = cosine(vectors(path, texts), ref), cosine(contrasted(path), ref_sided)
            print(f"{name}: {path.stat().st_size / 1e6:.1f} MB; cosine with float32 min "
                  f"{cos.min():.4f} median {np.median(cos):.4f}; side-contrasted min "
                  f"{cos_sided.min():.4f} median {np.median(cos_sided):.4f}")


if __name__ == "__main__":
    main()
