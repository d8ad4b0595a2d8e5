"""Where a big batch's time goes on the cuda-graphs backend: the noise, the graph's
replay (sampling, decoding, de-normalisation), the copy to the host and the per-item arrays.

    python bench/gpu/throughput_parts.py [--batches 4096,16384] [--dtype bfloat16]

Medians of 5 runs after 2 warm-ups, ms and motions/s; noise drawn on the GPU (random seeds)
and on the host (one seed for the batch: what reproducing a batch costs).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from mlct.generate.bundle import read_bundle
from mlct.generate.backends.cuda_graphs import _to_host
from mlct.generate.load import cuda_graph_generator
from mlct.generate.bundle import bundled_model_dir

FRAMES, NFE = 196, 5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", default="4096,16384")
    parser.add_argument("--dtype", default="bfloat16")
    args = parser.parse_args()
    if not torch.cuda.is_available():
        parser.error("needs a GPU")
    gen = cuda_graph_generator(*read_bundle(bundled_model_dir()), "cuda", args.dtype)
    cond1 = gen.encode_text(["a person walks forward"])
    nets = gen.networks  # the cuda-graphs networks: their buckets, noise and graphs
    print(f"{'batch':>6} {'noise on':>8} {'noise':>7} {'replay':>7} {'to host':>8} {'total':>7} "
          f"{'motions/s':>10}")
    for batch in (int(b) for b in args.batches.split(",")):
        cond = cond1.expand(batch, -1).contiguous()
        lengths = [FRAMES] * batch
        frames = nets._frames(lengths)
        lens = nets._lengths_tensor(lengths, frames)
        for where, seed in (("gpu", None), ("host", 0)):
            parts = []
            for i in range(7):
                torch.cuda.synchronize()
                t0 = time.perf_counter()
                c, noise = nets._sampler_inputs(cond, NFE, seed, None)
                torch.cuda.synchronize()
                t1 = time.perf_counter()
                out = nets._graphs(("features", NFE, None, frames), c, noise, lens)
                torch.cuda.synchronize()
                t2 = time.perf_counter()
                _to_host(out, lengths)
                t3 = time.perf_counter()
                if i >= 2:
                    parts.append((t1 - t0, t2 - t1, t3 - t2))
            noise_s, replay_s, host_s = np.median(np.array(parts), axis=0)
            total = noise_s + replay_s + host_s
            print(f"{batch:>6} {where:>8} {noise_s * 1e3:>7.1f} {replay_s * 1e3:>7.1f} "
                  f"{host_s * 1e3:>8.1f} {total * 1e3:>7.1f} {batch / total:>10,.0f}", flush=True)


if __name__ == "__main__":
    main()
