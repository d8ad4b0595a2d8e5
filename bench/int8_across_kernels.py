"""The static site's int8 text encoder on the int8 kernels of every x86-64 CPU.

    python bench/int8_across_kernels.py      # a minute or two

ONNX Runtime's u8 x s8 product saturates pairs of products in int16 on a CPU without VNNI
(mlct/serve/site/int8_emulation.py rewrites a graph to compute what such a CPU computes). For four
dynamic quantizations of MiniLM (int8 weights as ONNX Runtime makes them; 7-bit weights,
reduce_range; uint8 weights, U8U8; int8 weights with pair-safe scales, mlct's quantize_int8)
prints the size, the cosine of the sentence vectors with float32's over the benchmark's 62
prompts (bench/data/quality_prompts.json) on this CPU's kernels and as a CPU without VNNI
computes them, and the time of one prompt on this CPU (best of 20, one thread).
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from mlct.serve.site.int8_emulation import as_non_vnni

PROMPTS = Path(__file__).parent / "data" / "quality_prompts.json"


def main() -> None:
    import onnx
    import onnxruntime as ort
    from onnxruntime.quantization import QuantType, quantize_dynamic
    from tokenizers import Tokenizer

    from mlct.generate.backends.onnx.convert import write_onnx_graphs
    from mlct.generate.backends.onnx.compact import QUANTIZED_OPS, quantize_int8
    from mlct.generate.bundle import bundled_model_dir
    from mlct.text.encoders import bundled_minilm_path

    data = json.loads(PROMPTS.read_text())
    texts = [item["text"] for key in ("paraphrases", "two_actions") for item in data[key]]
    tokenizer = Tokenizer.from_file(str(bundled_minilm_path() / "tokenizer.json"))
    ids = [np.array([tokenizer.encode(t).ids], dtype=np.int64) for t in texts]

    def session(model: onnx.ModelProto) -> ort.InferenceSession:
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.log_severity_level = 3
        return ort.InferenceSession(model.SerializeToString(), options,
                                    providers=["CPUExecutionProvider"])

    def vectors(sess: ort.InferenceSession) -> np.ndarray:
        return np.array([sess.run(["embedding"], {"ids": i, "mask": np.ones_like(i)})[0][0]
                         for i in ids], dtype=np.float64)

    def cosine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a * b).sum(1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)

    variants = {"int8 weights (ONNX Runtime's)": {"weight_type": QuantType.QInt8},
                "7-bit weights (reduce_range)": {"weight_type": QuantType.QInt8,
                                                 "reduce_range": True},
                "uint8 weights (U8U8)": {"weight_type": QuantType.QUInt8},
                "int8 weights, pair-safe scales (mlct's quantize_int8)": None}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        reference = write_onnx_graphs(bundled_model_dir(), tmp, fused_text=False) \
            / "text_encoder.onnx"
        ref = vectors(session(onnx.load(str(reference))))
        print(f"{len(texts)} prompts")
        for name, options in variants.items():
            path = tmp / "q.onnx"
            if options is None:
                quantize_int8(reference, path)
            else:
                quantize_dynamic(str(reference), str(path), per_channel=True,
                                 op_types_to_quantize=list(QUANTIZED_OPS), **options)
            model = onnx.load(str(path))
            native = session(model)
            cos = cosine(vectors(native), ref)
            non_vnni, rewritten = as_non_vnni(model)
            cos_non_vnni = cosine(vectors(session(non_vnni)), ref) if rewritten else cos
            feed = {"ids": ids[0], "mask": np.ones_like(ids[0])}
            times = []
            for _ in range(20):
                start = time.perf_counter()
                native.run(["embedding"], feed)
                times.append(time.perf_counter() - start)
            print(f"{name}: {path.stat().st_size / 1e6:.1f} MB; cosine with float32 min "
                  f"{cos.min():.4f} median {np.median(cos):.4f} here, min "
                  f"{cos_non_vnni.min():.4f} median {np.median(cos_non_vnni):.4f} without VNNI "
                  f"({rewritten} products rewritten); {min(times) * 1000:.1f} ms a prompt here")


if __name__ == "__main__":
    main()
