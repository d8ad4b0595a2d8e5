"""What the static site's smaller graphs cost: the text encoder and denoiser choices of
`mlct export-web` against the float32 / float16 graphs, in Python (ONNX Runtime), same noise.

    python bench/web_quantization.py [--prompts 30]

Exports the bundled model four times into a temporary folder (--text-encoder float32, int8,
int8-weights; --denoiser int8) and prints, for the benchmark's prompts
(bench/data/quality_prompts.json): the cosine of each text encoder's sentence vectors with the
float32 ones, and the mean joint distance between motions made with the same portable noise
(4 s, 5 NFE) by each variant and by the float32 text encoder + float16 denoiser; another seed's
distance for scale; the sizes of the graphs.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import torch

from mlct.serve.site.reference import generate_with_portable_noise
from mlct.serve.site import export_site, load_site_reference

PROMPTS = Path(__file__).resolve().parent / "data" / "quality_prompts.json"
VARIANTS = {"float32 text, float16 denoiser (reference)": {"text_encoder": "float32"},
            "--text-encoder int8 (default)": {"text_encoder": "int8"},
            "--text-encoder int8-weights": {"text_encoder": "int8-weights"},
            "--denoiser int8 (float32 text)": {"text_encoder": "float32", "denoiser": "int8"}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prompts", type=int, default=30, help="motions per variant")
    args = parser.parse_args()
    torch.set_num_threads(1)
    data = json.loads(PROMPTS.read_text())
    texts = [item["text"] for key in ("paraphrases", "two_actions") for item in data[key]]
    with tempfile.TemporaryDirectory() as tmp:
        generators = {}
        for i, (name, options) in enumerate(VARIANTS.items()):
            site = export_site("bundled", Path(tmp) / f"site{i}", **options)
            generators[name] = load_site_reference(site, threads=1)
            sizes = {p.name: p.stat().st_size / 1e6 for p in (site / "model").glob("*.onnx*")}
            print(f"{name}: " + ", ".join(f"{k} {v:.1f} MB" for k, v in sorted(sizes.items())))
        names = list(generators)
        reference = generators[names[0]]
        ref_emb = reference.encode_text(texts)
        ref_motions = [generate_with_portable_noise(reference, t, 80, 5, i)[1]
                       for i, t in enumerate(texts[:args.prompts])]
        other_seed = [np.linalg.norm(generate_with_portable_noise(reference, t, 80, 5, i + 1000)[1]
                                     - m, axis=-1).mean()
                      for i, (t, m) in enumerate(zip(texts, ref_motions))]
        print(f"\n{len(texts)} prompts for the cosines, {len(ref_motions)} motions (80 frames)")
        print(f"for scale, another seed: mean joint distance median {np.median(other_seed):.3f} m")
        for name in names[1:]:
            generator = generators[name]
            cos = (generator.encode_text(texts) * ref_emb).sum(1).numpy()
            gaps = [np.linalg.norm(generate_with_portable_noise(generator, t, 80, 5, i)[1] - m,
                                   axis=-1).mean()
                    for i, (t, m) in enumerate(zip(texts, ref_motions))]
            print(f"{name}: cosine min {cos.min():.4f} median {np.median(cos):.4f}; mean joint "
                  f"distance median {np.median(gaps):.3f} m, worst {max(gaps):.3f} m")


if __name__ == "__main__":
    main()
