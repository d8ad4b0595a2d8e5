"""How far the int8 denoiser (backend onnx-int8) moves the joints from float32 ONNX's.

    python bench/int8_joints.py --data SYNTH [--model DIR] [--limit N]

The same seeds through both (seed 0 each, one sample, no split into actions): the benchmark's
test captions at their real lengths, then the 42 hand-written paraphrases at 5 s. Prints the
joints' distance (mean, median, 99th percentile, largest), the root-relative pose's, and how many
motions move more than 1 cm on average: issue 17 keeps int8 only if joints move < 1 cm.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

import mlct
from mlct.data.layout import DatasetLayout
from mlct.generate.onnx_bundle import convert_to_onnx
from mlct.generate.pipeline import bundled_model_dir

PROMPTS = Path(__file__).parent / "data" / "quality_prompts.json"


def joints(gen: mlct.MotionGenerator, texts: list[str], lengths: list[int]) -> list[np.ndarray]:
    out = []
    for k in range(0, len(texts), 50):
        part = slice(k, k + 50)
        out += [m.joints for m in gen.generate(texts[part], lengths=lengths[part],
                                               seed=[0] * len(texts[part]), candidates=1,
                                               split_actions=False)]
    return out


def report(what: str, a: list[np.ndarray], b: list[np.ndarray]) -> None:
    dist = np.concatenate([np.linalg.norm(x - y, axis=-1).ravel() for x, y in zip(a, b)])
    pose = np.concatenate([np.linalg.norm((x - x[:, :1]) - (y - y[:, :1]), axis=-1).ravel()
                           for x, y in zip(a, b)])
    per = np.array([np.linalg.norm(x - y, axis=-1).mean() for x, y in zip(a, b)])
    mm = 1000
    print(f"{what}: joints mean {dist.mean() * mm:.1f} mm, median {np.median(dist) * mm:.1f}, "
          f"p99 {np.percentile(dist, 99) * mm:.0f}, largest {dist.max() * mm:.0f}; root-relative "
          f"pose mean {pose.mean() * mm:.1f}, largest {pose.max() * mm:.0f}; motions moving "
          f"> 1 cm on average: {(per > 0.01).sum()} of {len(per)} ({(per > 0.01).mean():.1%})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--limit", type=int, default=None, help="first N test motions")
    args = parser.parse_args()
    layout = DatasetLayout.existing(args.data)
    names = layout.read_split("test")[: args.limit]
    captions = [layout.read_texts(n)[0].caption for n in names]
    lengths = [min(len(layout.load_features(n)), 196) for n in names]
    paraphrases = [p["text"] for p in json.loads(PROMPTS.read_text())["paraphrases"]]
    with tempfile.TemporaryDirectory() as tmp:
        model = args.model or bundled_model_dir()
        gens = [mlct.load(convert_to_onnx(model, Path(tmp) / name, read_only=True, int8=int8),
                          backend=backend)
                for name, int8, backend in (("f32", False, "onnx"),
                                            ("i8", True, "onnx-int8"))]
        for gen in gens:  # batches of 50: the graphs, not the torch networks that large
            gen.torch_min_batch = None  # batches are handed to (onnx_backend.TORCH_MIN_BATCH)
        report(f"{len(names)} test captions", *(joints(g, captions, lengths) for g in gens))
        five = [gens[0].frames_for(5.0)] * len(paraphrases)
        report(f"{len(paraphrases)} paraphrases, 5 s", *(joints(g, paraphrases, five)
                                                         for g in gens))


if __name__ == "__main__":
    main()
