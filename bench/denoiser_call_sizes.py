"""ONNX Runtime time of one batch-1 denoiser call at several network sizes (issue 17).

    python bench/denoiser_call_sizes.py [--threads 1] [--tokens 6] [--rounds 8]

Batch 1 streams the denoiser's weights once per sampling step, so its size sets the step's
floor. Each size is built from the small preset with overrides (seeded random weights: the time
does not depend on the values), exported as `mlct convert --onnx` exports the bundle's denoiser
(mlct.generate.onnx_bundle), and called with the sizes taking turns, --rounds rounds of 40
calls; medians in ms, and 5 calls (5 NFE) beside them.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

SIZES = {  # label: config overrides of the small preset (the skip transformer: odd layers)
    "5 x 256 (small preset)": [],
    "5 x 192": ["denoiser.width=192", "denoiser.ff_dim=768"],
    "3 x 256": ["denoiser.layers=3"],
    "3 x 192": ["denoiser.width=192", "denoiser.ff_dim=768", "denoiser.layers=3"],
    "3 x 128": ["denoiser.width=128", "denoiser.ff_dim=512", "denoiser.layers=3"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1, help="ONNX Runtime's intra-op threads")
    parser.add_argument("--tokens", type=int, default=6, help="latent tokens (the bundle: 6)")
    parser.add_argument("--rounds", type=int, default=8)
    args = parser.parse_args()
    import numpy as np
    import torch

    from mlct.config import load_config
    from mlct.generate.onnx_bundle import DENOISER_IO
    from mlct.nn.build import build_denoiser
    from mlct.nn.inference import for_inference
    from mlct.onnx_io import export_graph, session

    torch.manual_seed(0)
    folder = Path(tempfile.mkdtemp())
    calls = {}
    for i, (label, overrides) in enumerate(SIZES.items()):
        config = load_config("small", [f"ae.n_tokens={args.tokens}", *overrides])
        denoiser = for_inference(build_denoiser(config, 384).eval(), prepack=False)
        x, t, text = torch.randn(1, args.tokens, 64), torch.tensor([0.5]), torch.randn(1, 384)
        graph = folder / f"denoiser{i}.onnx"
        export_graph(denoiser, (x, t, text), graph, *DENOISER_IO,
                     {k: {0: "batch"} for k in (*DENOISER_IO[0], *DENOISER_IO[1])})
        params = sum(p.numel() for p in denoiser.parameters())
        feed = {"x_t": x.numpy(), "t": t.numpy(), "text": text.numpy()}
        calls[label] = (session(graph, args.threads), feed, params)
    times: dict[str, list[float]] = {label: [] for label in calls}
    for _ in range(args.rounds):
        for label, (run, feed, _) in calls.items():
            for _ in range(5):  # warm-up
                run.run(None, feed)
            start = time.perf_counter()
            for _ in range(40):
                run.run(None, feed)
            times[label].append((time.perf_counter() - start) / 40 * 1e3)
    first = float(np.median(next(iter(times.values()))))
    print(f"batch 1, {args.tokens} tokens, {args.threads} ONNX Runtime thread(s); medians")
    for label, values in times.items():
        ms = float(np.median(values))
        print(f"{label:<24} {calls[label][2] / 1e6:5.2f} M params  {ms:6.3f} ms/call  "
              f"5 calls {5 * ms:5.2f} ms  ({first / ms:.2f}x the first)")


if __name__ == "__main__":
    main()
