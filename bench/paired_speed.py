"""Batch-1 latency of several models (or graph variants) side by side, taking turns in one process.

Why: on a shared 2-core host the quick bench's medians of one model move by 30 % from one run to
the next (docs/performance.md), more than a decoder swap or a fused text graph changes, so a
comparison of two separate runs says nothing. Here every model runs one round, then the next,
for several rounds; each round reports every model's median, and the ratios are taken within a
round (paired), so the host's drift cancels.

    python bench/paired_speed.py --models bundled /path/to/model [bundled:unfused-text] \\
        --rounds 8 --calls 30 --threads 2

MODEL is a model directory, "bundled", or "paper" / "paper-int8" (bench/inference_speed.py's
paper-size networks, seeded random weights, converted in float32 / with --int8), optionally with variants after a colon, joined by
"+" (bundled:whole-grid+matmul-add-fusion), each as the graphs were before a change:
"unfused-text" the text encoder of standard ONNX operators (write_minilm_graph(fused=False))
instead of the fused one; "whole-grid" a decoder that convolves every grid cell whatever the
clip's length (before nn/conv_autoencoder.py's DECODE_MARGIN);
"matmul-add-fusion" ONNX Runtime's MatMulAddFusion on (before onnx_io.DISABLED_OPTIMIZERS);
"spinning-steps" / "one-thread-steps" batch 1's steps on two threads spinning within the run /
on one thread, whatever the machine's load (onnx_io.spin_now decides otherwise);
"static-spinning" the steps and the text encoder spinning by the machine's size alone
(onnx_io.spare_cores: 4 logical CPUs or more), not by how idle it is now. The onnx backend's
other choices measured here once (the steps apart from the decoder, the decoder's halves, the
fused attentions, the big graph spinning, the candidates through the steps' graph, the torch
work on one thread) are fixed now (backends/onnx/networks.py says why, with their figures).
--generate also times generate() itself, as a user calls it: a 5 s motion of a caption seen
before, the model's best of N candidates, keep-going and planted feet included (column "gen").
--busy N runs N busy loops beside the rounds (started after loading), the load spin_now is to
see: `--busy 1` on 2 cores is a machine with one core taken.
--frames sets the clip's length (196: 9.8 s, the bench's; 100: 5 s, generate()'s default).
Per call, as bench/inference_speed.py times them: warm = one sample of a caption already
encoded (text memo, anchors' pull, sample_features: 5 steps and the decoder, 196 frames; the
paper's AITS, the figure the targets count); text = the text encoder on a new sentence; cold =
warm + text. The onnx backend, float32.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# the same prompts, length and paper-size networks as bench/inference_speed.py
from mlct.eval.speed import FRAMES, TEXTS, onnx_generator


VARIANTS = ("unfused-text", "whole-grid", "matmul-add-fusion", "spinning-steps",
            "one-thread-steps", "static-spinning")


def load(spec: str, folder: Path, frames: int = FRAMES) -> Any:
    """The onnx-backend generator of a model spec (see the module docstring)."""
    import mlct
    import mlct.nn.conv_autoencoder as conv
    import mlct.onnx_io as onnx_io
    from mlct.generate.backends.onnx.bundle import ONNX_DIR, TEXT_ENCODER
    from mlct.generate.backends.onnx.convert import convert_to_onnx
    from mlct.generate.bundle import bundled_model_dir
    from mlct.text.minilm_onnx import write_minilm_graph

    name, _, variant = spec.partition(":")
    chosen = set(variant.split("+")) if variant else set()
    if chosen - set(VARIANTS):
        raise SystemExit(f"unknown variant {variant!r} of {name}: one or more of {VARIANTS}, "
                         f"joined by +")
    paper = name in ("paper", "paper-int8")
    model = bundled_model_dir() if name == "bundled" else Path(name)
    # the variants' switches, as they were before each change; restored on the way out
    margin, disabled = conv.DECODE_MARGIN, onnx_io.DISABLED_OPTIMIZERS
    if "whole-grid" in chosen:  # the graph is traced with the margin as a constant
        conv.DECODE_MARGIN = 10**6
    if "matmul-add-fusion" in chosen:  # every session is made (below) with it on
        onnx_io.DISABLED_OPTIMIZERS = ()
    try:
        if paper:  # written to folder/model, converted beside it
            (folder / "model").mkdir(parents=True)
            out = onnx_generator("humanml3d", "consistency", str(folder / "model"),
                                 int8=name == "paper-int8").networks.graphs.denoiser.parent.parent
        else:
            out = convert_to_onnx(model, folder, read_only=name == "bundled")
        if "unfused-text" in chosen:
            import json

            spec_name = json.loads((out / "config.json").read_text())["text_encoder"]
            write_minilm_graph(spec_name, out / ONNX_DIR / TEXT_ENCODER, fused=False)
        gen = mlct.load(out, backend="onnx")  # ONNX Runtime threads follow torch's
        nets = gen.networks
        if chosen & {"spinning-steps", "one-thread-steps"}:
            nets.spinning = "spinning-steps" in chosen
        if "static-spinning" in chosen:
            if nets.spinning is None:
                nets.spinning = nets.threads >= 2 and onnx_io.spare_cores(2)
            gen.text_encoder.spinning = onnx_io.spare_cores(gen.text_encoder.threads)
        warm_ms(gen, len(TEXTS) + 2, 0, frames)  # the text memo and the sampler graph's
        text_ms(gen, 4, 0)  # sessions, made here under the switches
    finally:
        conv.DECODE_MARGIN, onnx_io.DISABLED_OPTIMIZERS = margin, disabled
    return gen


def warm_ms(gen: Any, calls: int, offset: int, frames: int = FRAMES) -> float:
    """Median ms of generate()'s work for a caption already encoded (bench/inference_speed.py's
    time_pipeline)."""
    times = []
    for i in range(calls):
        text = TEXTS[(offset + i) % len(TEXTS)]
        start = time.perf_counter()
        cond = gen.sampling_text(gen.encode_text([text]))
        gen.sample_features(cond, 5, [i], None, [frames])
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000.0


def generate_ms(gen: Any, calls: int, offset: int) -> float:
    """Median ms of generate() of a 5 s motion of a caption already encoded, the model's
    defaults otherwise (best of N, keep-going, planted feet)."""
    times = []
    for i in range(calls):
        text = TEXTS[(offset + i) % len(TEXTS)]
        start = time.perf_counter()
        gen.generate(text, seconds=5, seed=offset * 1000 + i)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000.0


def text_ms(gen: Any, calls: int, offset: int) -> float:
    """Median ms of the text encoder on a sentence it has not memoised (encode, not the memo)."""
    times = []
    for i in range(calls):
        text = TEXTS[(offset + i) % len(TEXTS)]
        start = time.perf_counter()
        gen.text_encoder.encode([text])
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", nargs="+", required=True)
    parser.add_argument("--rounds", type=int, default=8)
    parser.add_argument("--calls", type=int, default=30)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--frames", type=int, default=FRAMES)
    parser.add_argument("--busy", type=int, default=0, metavar="N",
                        help="busy loops running beside the rounds")
    parser.add_argument("--generate", action="store_true",
                        help="also time generate() of a 5 s motion, the model's defaults")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(args.threads)
    root = Path(tempfile.mkdtemp(prefix="mlct-paired-"))
    gens = {spec: load(spec, root / f"m{i}", args.frames) for i, spec in enumerate(args.models)}
    rounds: dict[str, list[tuple[float, float, float]]] = {spec: [] for spec in gens}
    if args.generate:  # the text memo, the graphs and the halves of generate()'s own path
        for gen in gens.values():
            generate_ms(gen, len(TEXTS) + 2, 0)
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
            for _ in range(args.busy)]
    try:
        for r in range(args.rounds):
            for spec, gen in gens.items():
                rounds[spec].append((warm_ms(gen, args.calls, r, args.frames),
                                     text_ms(gen, args.calls, r),
                                     generate_ms(gen, args.calls, r) if args.generate
                                     else float("nan")))
    finally:
        for loop in busy:
            loop.kill()
    first = args.models[0]
    print(f"batch 1, {args.frames} frames, 5 NFE, onnx backend, {args.threads} threads; "
          f"{args.rounds} rounds of {args.calls} calls, the models taking turns; ms"
          + (f"; {args.busy} busy loop(s) beside" if args.busy else ""))
    width = max(44, *map(len, args.models))  # a model's spec whole, however long
    print(f"{'model':<{width}} {'warm med':>8} {'range':>13} {'text med':>8} {'cold med':>8} "
          f"{'warm/first':>10} {'cold/first':>10}"
          + (f" {'gen med':>8} {'gen/first':>9}" if args.generate else ""))
    for spec, values in rounds.items():
        warm = [w for w, _, _ in values]
        cold = [w + t for w, t, _ in values]
        made = [g for _, _, g in values]
        base_warm = [w for w, _, _ in rounds[first]]
        base_cold = [w + t for w, t, _ in rounds[first]]
        base_made = [g for _, _, g in rounds[first]]
        warm_ratio = statistics.median(a / b for a, b in zip(warm, base_warm))
        cold_ratio = statistics.median(a / b for a, b in zip(cold, base_cold))
        line = (f"{spec:<{width}} {statistics.median(warm):8.2f} "
                f"{min(warm):6.2f}-{max(warm):<6.2f} "
                f"{statistics.median(t for _, t, _ in values):8.2f} "
                f"{statistics.median(cold):8.2f} {warm_ratio:10.3f} {cold_ratio:10.3f}")
        if args.generate:
            made_ratio = statistics.median(a / b for a, b in zip(made, base_made))
            line += f" {statistics.median(made):8.2f} {made_ratio:9.3f}"
        print(line)
    print("(ratios: the median over rounds of each round's ratio to the first model)")


if __name__ == "__main__":
    main()
