"""The onnx backend's sampler graph at batch 1, as built before and after its constants were
baked in: side by side, taking turns, one ONNX Runtime thread.

    python bench/sampler_graph_variants.py [--model DIR] [--nfe 5] [--runs 200] [--rounds 3]

Variants (onnx_sampler.py): "inputs", the step times and coefficients fed per call and the batch
dimension free (the graph before 2026-11-26); "baked", the times and coefficients constants of
the graph and the batch fixed at 1 (what the backend runs at batch 1 now). Prints each one's
operator count after ONNX Runtime's optimizations, the largest feature difference between them,
and the median ms per call of each round.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import mlct
from mlct.generate.onnx_bundle import convert_to_onnx
from mlct.generate.onnx_sampler import fixed_batch, sampler_model, step_coefficients
from mlct.generate.pipeline import bundled_model_dir, generators_for
from mlct.onnx_io import onnxruntime_module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    ort = onnxruntime_module()
    import onnx

    with tempfile.TemporaryDirectory() as tmp:
        folder = convert_to_onnx(args.model or bundled_model_dir(), Path(tmp) / "model",
                                 read_only=True)
        gen = mlct.load(folder, backend="onnx")
        shape = (1, *gen.ae.latent_shape)
        common = dict(clamp=gen.clamp, latent_scale=gen.config.schedule.latent_scale,
                      mean=gen.mean.numpy(), std=gen.std.numpy())
        coefficients = step_coefficients(gen.sampler, args.nfe)
        graphs = {
            "inputs": sampler_model(gen.graphs.denoiser, gen.graphs.decoder, args.nfe,
                                    **common).SerializeToString(),
            "baked": fixed_batch(sampler_model(gen.graphs.denoiser, gen.graphs.decoder, args.nfe,
                                               coefficients=coefficients, **common)
                                 .SerializeToString(), 1),
        }
        sessions, counts = {}, {}
        for name, graph in graphs.items():
            options = ort.SessionOptions()
            options.intra_op_num_threads = 1
            options.log_severity_level = 3
            options.optimized_model_filepath = str(Path(tmp) / f"{name}.onnx")
            sessions[name] = ort.InferenceSession(graph, options,
                                                  providers=["CPUExecutionProvider"])
            counts[name] = len(onnx.load(str(Path(tmp) / f"{name}.onnx")).graph.node)
        rng = np.random.default_rng(0)
        width = next(i.shape[1] for i in sessions["baked"].get_inputs() if i.name == "text")
        text = rng.standard_normal((1, width))
        feeds = {"x": gen.sampler.noise(shape, generators_for(0)).numpy(),
                 "noise": rng.standard_normal((args.nfe, *shape)).astype(np.float32),
                 "text": (text / np.linalg.norm(text)).astype(np.float32),
                 "valid": np.ones((1, gen.max_frames), bool), **coefficients}
        outs = {}
        for name, s in sessions.items():
            wanted = {i.name for i in s.get_inputs()}
            outs[name] = s.run(["features"], {k: v for k, v in feeds.items() if k in wanted})[0]
        gap = float(np.abs(outs["inputs"] - outs["baked"]).max())
        print(f"sampler graph, {args.nfe} NFE, batch 1, {gen.max_frames} frames, 1 thread")
        print("operators after optimization: " + ", ".join(f"{k} {v}" for k, v in counts.items())
              + f"; largest feature difference {gap:.2e}")
        for round_ in range(args.rounds):
            medians = {}
            for name, s in sessions.items():
                wanted = {i.name for i in s.get_inputs()}
                f = {k: v for k, v in feeds.items() if k in wanted}
                for _ in range(10):
                    s.run(None, f)
                times = []
                for _ in range(args.runs):
                    start = time.perf_counter()
                    s.run(None, f)
                    times.append(time.perf_counter() - start)
                medians[name] = 1000 * float(np.median(times))
            print(f"round {round_ + 1}: " + ", ".join(f"{k} {v:.2f} ms" for k, v in
                                                     medians.items())
                  + f"; inputs / baked {medians['inputs'] / medians['baked']:.2f}x")


if __name__ == "__main__":
    main()
