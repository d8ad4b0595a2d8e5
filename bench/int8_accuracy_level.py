"""The int8 denoiser's arithmetic: ONNX Runtime's MatMulNBits with accuracy_level 4 (int8
products, the activations quantized per block at run time: the shipped onnx-int8) against
accuracy_level 1 (the int8 weights dequantized, float32 products). Does keeping the
activations in float32 bring the joints within issue 17's 1 cm of float32's, and at what speed?

    python bench/int8_accuracy_level.py --data SYNTH [--limit 150]

The joints as bench/int8_joints.py reads them (same seeds, one sample, whole prompts), then
warm generate() at batch 1, 196 frames, 5 NFE, the three models taking turns (6 rounds of 30).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import onnxruntime.quantization.matmul_nbits_quantizer as nbits

import mlct
from mlct.data.layout import DatasetLayout
from mlct.generate.onnx_bundle import convert_to_onnx
from mlct.generate.pipeline import bundled_model_dir

sys.path.insert(0, str(Path(__file__).parent))
from int8_joints import PROMPTS, joints, report  # noqa: E402

TEXT = "a person walks forward, then waves with the right hand"


def config_at(level: int) -> type:
    """MatMulNBits' config class with accuracy_level forced (onnx_compact passes 4)."""
    class Forced(nbits.DefaultWeightOnlyQuantConfig):
        def __init__(self, *args, **kwargs):
            kwargs["accuracy_level"] = level
            super().__init__(*args, **kwargs)
    return Forced


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--limit", type=int, default=150, help="first N test motions")
    args = parser.parse_args()
    real = nbits.DefaultWeightOnlyQuantConfig
    with tempfile.TemporaryDirectory() as tmp:
        dirs = {"float32": convert_to_onnx(bundled_model_dir(), Path(tmp) / "f32", read_only=True)}
        for level in (4, 1):
            nbits.DefaultWeightOnlyQuantConfig = config_at(level)
            try:
                dirs[f"int8, level {level}"] = convert_to_onnx(
                    bundled_model_dir(), Path(tmp) / f"l{level}", read_only=True, int8=True)
            finally:
                nbits.DefaultWeightOnlyQuantConfig = real
        gens = {k: mlct.load(d, backend="onnx" if k == "float32" else "onnx-int8")
                for k, d in dirs.items()}
        layout = DatasetLayout.existing(args.data)
        names = layout.read_split("test")[: args.limit]
        captions = [layout.read_texts(n)[0].caption for n in names]
        lengths = [min(len(layout.load_features(n)), 196) for n in names]
        paraphrases = [p["text"] for p in json.loads(PROMPTS.read_text())["paraphrases"]]
        five = [gens["float32"].frames_for(5.0)] * len(paraphrases)
        reference = joints(gens["float32"], captions, lengths)
        reference_para = joints(gens["float32"], paraphrases, five)
        for name in ("int8, level 4", "int8, level 1"):
            report(f"{name}: {len(names)} test captions", reference,
                   joints(gens[name], captions, lengths))
            report(f"{name}: {len(paraphrases)} paraphrases, 5 s", reference_para,
                   joints(gens[name], paraphrases, five))
        once = dict(lengths=[196], seed=[0], candidates=1, split_actions=False)
        for gen in gens.values():
            for _ in range(5):
                gen.generate([TEXT], **once)
        times: dict[str, list[float]] = {name: [] for name in gens}
        for _ in range(6):
            for name, gen in gens.items():
                start = time.perf_counter()
                for _ in range(30):
                    gen.generate([TEXT], **once)
                times[name].append((time.perf_counter() - start) / 30 * 1000)
        for name, values in times.items():
            print(f"{name}: warm generate(), ms per round {' '.join(f'{v:.2f}' for v in values)}; "
                  f"median {np.median(values):.2f}")


if __name__ == "__main__":
    main()
