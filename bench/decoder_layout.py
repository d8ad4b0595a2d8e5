"""The bundled decoder with its conv stacks as trained (Conv1d over (B, C, T)) against the
channels-last stacks with fused GELUs (mlct.nn.inference.ChannelsLastConvs), one process, turn
by turn, at several batch sizes; the torch backend, 196 frames. Also sampling + decoding at the
default NFE (what the batched throughput of bench/inference_speed.py times).

    python bench/decoder_layout.py [--batches 1 8 64 512] [--rounds 7] [--threads 2]
                                   [--dtypes float32 bfloat16]

Prints medians in ms, motions/s and the ratio, and the largest difference between the two
decoders' features (float32: the same function; bfloat16: both round the products).
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 8, 64, 512])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--dtypes", nargs="+", default=["float32", "bfloat16"])
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    from mlct.generate.bundle import read_bundle
    from mlct.generate.pipeline import MotionGenerator, bundle_networks, bundled_model_dir
    from mlct.nn.inference import for_inference

    meta, tensors = read_bundle(bundled_model_dir())
    print(f"bundled model, torch backend, {args.threads} threads, 196 frames, "
          f"{args.rounds} rounds each way in turn; medians")
    print(f"{'dtype':9} {'batch':>5} {'part':16} {'as trained':>12} {'channels-last':>14} "
          f"{'gain':>6} {'motions/s':>18} {'max |diff|':>10}")
    for dtype in args.dtypes:
        gen = MotionGenerator(meta, tensors, dtype=dtype)
        plain_ae = for_inference(bundle_networks(gen.config, meta, tensors)[0], dtype,
                                 channels_last=False)
        fast_ae = gen.ae
        texts = ["a person walks forward", "a person jumps twice", "a person waves",
                 "a person kicks with the left leg"]
        cond_all = gen.encode_text(texts)
        for batch in args.batches:
            cond = cond_all[torch.arange(batch) % len(texts)]
            z = gen.sample_latents(cond, None, list(range(batch)), None)

            def decode(ae, z=z, batch=batch):
                gen.ae = ae
                return gen.decode(z, [196] * batch)

            def full(ae, cond=cond, batch=batch):
                gen.ae = ae
                return gen.sample_features(cond, None, list(range(batch)), None, [196] * batch)

            diff = max(float(abs(a - b).max()) for a, b in zip(decode(plain_ae), decode(fast_ae)))
            for part, fn in (("decode", decode), ("sample + decode", full)):
                times: dict[str, list[float]] = {"plain": [], "fast": []}
                for ae in (plain_ae, fast_ae):
                    fn(ae)  # warm-up
                for _ in range(args.rounds):
                    for name, ae in (("plain", plain_ae), ("fast", fast_ae)):
                        start = time.perf_counter()
                        fn(ae)
                        times[name].append(time.perf_counter() - start)
                plain, fast = (statistics.median(times[k]) for k in ("plain", "fast"))
                print(f"{dtype:9} {batch:>5} {part:16} {plain * 1e3:>10.1f}ms "
                      f"{fast * 1e3:>12.1f}ms {plain / fast:>5.2f}x "
                      f"{batch / plain:>8.1f} -> {batch / fast:>7.1f} {diff:>10.2e}", flush=True)
        gen.ae = fast_ae


if __name__ == "__main__":
    main()
