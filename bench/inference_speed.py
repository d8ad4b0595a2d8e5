"""Inference speed: AITS split, throughput, peak memory, and the machine's limit.

    python bench/inference_speed.py [--quick] [--device cpu|cuda] [--dtypes float32,bfloat16]
                                    [--backends torch,onnx,onnx-spinning,onnx-int8,...]
                                    [--threads N] [--runs 20] [--json OUT.json]
    python bench/inference_speed.py --headline [--runs 30]

The headline (first in every run; --headline: alone, ~20 s): in a fresh process on what
`mlct.load()` picks (onnx on a CPU, no torch imported), generate() with its defaults for a
5 s motion of a sentence seen before (target <= 25 ms), and the paper's measure: one sample of
5 s at the default NFE, warm (the sentence seen before: its vector from the memo) and cold
(a new sentence: the text encoder runs too), targets <= 5 and <= 10 ms. Medians.

Models: the bundled small consistency model ("small CM"; --small-model DIR times another
bundle in its place); the paper-size networks of the humanml3d preset ("paper CM"); the latent
diffusion baseline at both sizes ("... LDM": 50 DDIM steps, classifier-free guidance as one
batch of 2 per step). Paper-size and LDM networks get seeded random weights: the time does not
depend on the values. Text encoder: the bundled MiniLM.

Per model, backend, dtype and NFE, at batch 1 and 196 frames: text (encoder run), sampling and
decoding each timed on their own (mlct.eval.aits.time_inference, medians over --runs after
warm-up); "warm" is what generate() runs for a caption seen before (the text from the memo, then
sample_features: on the onnx backends the one-call sampler graph); "cold" adds a text-encoder
run. Throughput: sample_features of B motions (random seeds) at the default NFE, for B = 1, 8, 64, 512, 4096
until the next size is predicted to exceed the time budget or the free memory; peak memory is the
process's max RSS (CPU) or the allocator's peak (CUDA).

The limit: FLOPs counted by torch.utils.flop_counter per part (text: the median over the bench's
captions; one denoiser step; decoding) and bytes = the weights each part reads (every parameter
once per network pass; activations at batch 1 are at most ~1 MB and stay in cache, so they are
not counted). The machine is measured
here, each the best of 10 or more runs: peak matmul FLOP/s of a large GEMM in the dtype on all
threads, and read bandwidth over a buffer the size of each part's weights (cache-resident when
they fit, as they would be); both again after the model's timings, the better of the two kept
(a slow spell of the host must not raise the limit). A part's best time is max(FLOPs / peak,
bytes / bandwidth); the limit sums the parts (no term for per-operation overhead: that is what
the ratio shows). A batch of B: B times the FLOPs, the same bytes (the weights are read once per
pass). onnx-int8's step reads the bytes of its graph's weights (int8, their scales, the float32
products left).

Backends: torch, eager PyTorch through mlct.nn.inference's layers, in every dtype; onnx, the
ONNX Runtime backend (CPU, float32; the model is written to a temporary directory and converted
first, untimed); onnx-int8, the same converted with `mlct convert --onnx --int8` (the
denoiser's MatMuls dynamically quantized to int8; `--backend onnx-int8`, not the default:
docs/performance.md); onnx-spinning, the onnx backend with batch 1's steps on two threads that
spin within the run (what it does by itself where two logical CPUs stay free beside them:
onnx_io.spare_cores);
torch-compiled (only when named: compiling takes minutes per model and batch size), the
denoiser backbone and decoder under torch.compile with plain (unpacked) products, which inductor
can lower. The limit is the model's, whichever backend runs it (but for onnx-int8's weight bytes).

Each model runs in its own process, so peak memory is its own. --device cuda runs the networks
in bfloat16 (not run in this repository's CI; needs a GPU), on the torch backend (eager) and the
cuda-graphs backend (sampler, decoder and text encoder replayed from CUDA graphs); torch-compiled
there is torch.compile(mode="reduce-overhead"). Throughput on a GPU goes on to B = 16384.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mlct.eval.speed import (DEFAULT_FRAMES, FRAMES, SMALL_MODEL_ENV, TEXT_DIM, TEXTS,
                              bundle_in_memory, onnx_generator, small_model_dir)

MODELS = {  # label: (preset, sampler, NFEs; for DDIM the step count)
    "small CM": ("small", "consistency", (1, 3, 5, 10)),
    "paper CM": ("humanml3d", "consistency", (1, 3, 5, 10)),
    "paper LDM": ("humanml3d", "ddim", (50,)),
    "small LDM": ("small", "ddim", (50,)),
}
BATCHES = (1, 8, 64, 512, 4096)
HEADLINE_TARGETS_MS = {"generate": 25.0, "warm": 5.0, "cold": 10.0}
HEADLINE_PROMPT = "a person walks forward"
GPU_BATCHES = (*BATCHES, 16384)  # a GPU's throughput keeps growing past 4096
def _best_time(fn: Callable[[], Any], reps: int, sync: Callable[[], None]) -> float:
    """Shortest seconds of fn over reps runs, after one untimed run: a roof of the machine is
    the best it does (other processes only slow it down)."""
    fn()
    times = []
    for _ in range(reps):
        sync()
        start = time.perf_counter()
        fn()
        sync()
        times.append(time.perf_counter() - start)
    return min(times)


def _syncer(device: Any) -> Callable[[], None]:
    import torch

    return (lambda: torch.cuda.synchronize(device)) if device.type == "cuda" else (lambda: None)


def peak_matmul_flops(dtype: Any, device: Any) -> float:
    """FLOP/s of a large square GEMM in dtype on all threads (the compute roof)."""
    import torch

    n = 8192 if device.type == "cuda" else 2048
    a, b = torch.randn(n, n, device=device).to(dtype), torch.randn(n, n, device=device).to(dtype)
    return 2 * n**3 / _best_time(lambda: a @ b, 10, _syncer(device))


def read_bandwidth(nbytes: int, device: Any) -> float:
    """Bytes/s reading a buffer of nbytes (a sum; a copy on CUDA counts read + write)."""
    import torch

    n = max(nbytes // 4, 1 << 16)
    buf = torch.randn(n, device=device)
    reps = max(10, min(200, int(4e9 // (4 * n))))
    if device.type == "cuda":
        out = torch.empty_like(buf)
        return 2 * 4 * n / _best_time(lambda: out.copy_(buf), reps, _syncer(device))
    return 4 * n / _best_time(lambda: buf.sum(), reps, _syncer(device))


def variant(meta: dict[str, Any], tensors: dict[str, Any], layers: str, text_once: bool,
            inference_mode: bool = True, dtype: str = "float32") -> Any:
    """A generator whose networks run as `layers` says: "torch" (the modules as trained:
    nn.TransformerEncoderLayer, nn.Linear), "fast" (mlct.nn.inference, plain products) or
    "packed" (the default); text_once=False recomputes the text and time terms every step;
    inference_mode=False samples and decodes under no_grad instead."""
    import torch

    from mlct.nn.build import build_autoencoder, build_denoiser
    from mlct.nn.inference import for_inference
    from mlct.generate.load import torch_generator
    from mlct.io import strip_prefix

    gen = torch_generator(meta, tensors, dtype=dtype)
    if layers != "packed":
        ae = build_autoencoder(gen.config, meta["feature_dim"])
        ae.load_state_dict(strip_prefix(tensors, "decoder"), strict=False)
        den = build_denoiser(gen.config, meta["text_dim"])
        den.load_state_dict(strip_prefix(tensors, "denoiser"))
        nets = gen.networks
        nets.decoder, nets.denoiser = (ae.eval().requires_grad_(False),
                                       den.eval().requires_grad_(False))
        if layers == "fast":
            for_inference(gen.ae, dtype, prepack=False)
            for_inference(gen.denoiser, dtype, prepack=False)
    if not text_once:
        gen.denoiser.condition_terms = None  # the samplers then call it without a cache
    if not inference_mode:
        from mlct.generate.backends.pytorch import TorchNetworks

        for name in ("latents", "decode"):
            plain = getattr(TorchNetworks, name).__wrapped__  # under the decorator
            setattr(gen.networks, name, torch.no_grad()(plain.__get__(gen.networks)))
    return gen


def _compile_for_cuda(gen: Any) -> None:
    """Fewer launches on the GPU: the two transformer stacks compiled with CUDA graphs
    ("reduce-overhead"); the condition terms and the heads stay eager (a few launches)."""
    import torch

    gen.denoiser.backbone = torch.compile(gen.denoiser.backbone, mode="reduce-overhead")
    gen.ae.decoder = torch.compile(gen.ae.decoder, mode="reduce-overhead")  # either architecture


def _compile_for_cpu(gen: Any) -> None:
    """torch.compile (inductor, default mode) of the denoiser's backbone and the decoder: the
    parts that run per step and per motion; compilation happens in the warm-up runs."""
    import torch

    gen.denoiser.backbone = torch.compile(gen.denoiser.backbone, dynamic=False)
    gen.ae.decoder = torch.compile(gen.ae.decoder, dynamic=False)


def time_pipeline(gen: Any, nfe: int, runs: int, warmup: int, frames: int = FRAMES) -> float:
    """Median ms of what generate() runs for a seen caption: the text from the memo, the
    text anchors' pull (sampling_text, where the model has them), then sample_features
    (sampling and decoding; on the onnx backend the one-call sampler graph, built at the second
    call). Joint recovery (~0.4 ms) is not included, as in AITS."""
    import numpy as np

    times = []
    for i in range(warmup + runs):
        start = time.perf_counter()
        cond = gen.sampling_text(gen.encode_text([TEXTS[i % len(TEXTS)]]))
        gen.sample_features(cond, nfe, [i], None, [frames])
        if i >= warmup:
            times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1000.0


def _weight_bytes(*modules: Any) -> int:
    return sum(p.numel() * p.element_size() for m in modules for p in m.parameters())


def _graph_weight_bytes(graph: Any) -> int:
    """Bytes of an ONNX graph's stored weights (its initializers), as a pass reads them."""
    import onnx
    from onnx import numpy_helper

    return sum(numpy_helper.to_array(t).nbytes for t in onnx.load(str(graph)).graph.initializer)


def _embedding_bytes(module: Any) -> int:
    """Bytes of module's embedding tables: a pass reads a few of their rows, not all of them
    (MiniLM's word table is 45 of its 86 MB)."""
    import torch

    tables = [m.weight for m in module.modules()  # nn.Embedding, or mlct.text.bert's tables
              if isinstance(m, torch.nn.Embedding) or type(m).__name__ == "_Table"]
    return sum(w.numel() * w.element_size() for w in tables)


def part_costs(gen: Any) -> dict[str, dict[str, float]]:
    """FLOPs and weight bytes at batch 1 of the text encoder, one sampling step and decoding."""
    import torch
    from torch.utils.flop_counter import FlopCounterMode

    from mlct.generate.bundle import ENCODER_PREFIXES

    def linear_flops(x: Any, w: Any, *args: Any, out_shape: Any = None, **kwargs: Any) -> int:
        return 2 * math.prod(out_shape) * x[-1]  # (..., K) x (N, K)^T

    def conv_flops(x: Any, w: Any, *args: Any, out_shape: Any = None, **kwargs: Any) -> int:
        return 2 * math.prod(out_shape) * math.prod(w[1:])  # w: (C_out, C_in / groups, kh, kw)

    # the packed products and fused convolutions of mlct.nn.inference are ops the counter does
    # not know
    mapping = {torch.ops.mkldnn._linear_pointwise: linear_flops,
               torch.ops.mkldnn._convolution_pointwise: conv_flops}

    def flops(fn: Callable[[], Any]) -> float:
        with FlopCounterMode(display=False, custom_mapping=mapping) as counter, torch.no_grad():
            fn()
        return float(counter.get_total_flops())

    cond = gen.encode_text([TEXTS[0]])
    z = gen.sample_latents(cond, 1, seed=0)
    ae = gen.ae
    model = getattr(gen.text_encoder, "model", None)
    return {
        # the text encoder's time is a median over TEXTS (a sided one runs with its mirror:
        # two rows), so its FLOPs are too
        "text": {"flops": statistics.median(flops(lambda text=text: gen.text_encoder.encode(
                     [text])) for text in TEXTS),
                 "bytes": _weight_bytes(model) - _embedding_bytes(model)
                 if model is not None else 0.0},
        "step": {"flops": flops(lambda: gen.sample_latents(cond, 1, seed=0)),
                 "bytes": _weight_bytes(gen.denoiser)},
        "decode": {"flops": flops(lambda: gen.decode(z, [FRAMES])),
                   "bytes": sum(p.numel() * p.element_size() for n, p in ae.named_parameters()
                                if not n.startswith(ENCODER_PREFIXES))},
    }


def throughput(gen: Any, budget_s: float, sync: Callable[[], None]) -> list[dict[str, Any]]:
    """Motions/s of sampling + decoding at the default NFE, growing B while it stays in budget."""
    import torch

    cond = gen.encode_text(TEXTS)
    rows: list[dict[str, Any]] = []
    base_rss = _peak_mb(gen.device)
    for batch in GPU_BATCHES if gen.device.type == "cuda" else BATCHES:
        if rows:
            last = rows[-1]
            predicted = last["seconds"] * batch / last["batch"]
            grow_mb = max(last["peak_mb"] - base_rss, 1.0) * batch / last["batch"]
            free_mb = _free_mb(gen.device)
            if predicted > budget_s or grow_mb > free_mb * 0.5:
                why = (f"predicted {predicted:.0f} s > {budget_s:g} s" if predicted > budget_s
                       else f"needs ~{grow_mb / 1024:.1f} GiB of {free_mb / 1024:.1f} free")
                rows.append({"batch": batch, "skipped": why})
                break
        c = cond[torch.arange(batch) % len(TEXTS)]

        def run(c: Any = c, batch: int = batch) -> None:
            gen.sample_features(c, None, None, None, [FRAMES] * batch)  # random seeds

        if gen.device.type == "cuda":
            torch.cuda.reset_peak_memory_stats(gen.device)
        if not rows:
            run()  # the onnx backend builds its sampler graph at the second call
        # the onnx backend hands its first batch of torch_min_batch or more to torch networks
        # it builds then (a one-off, as the sampler graph): warmed up whatever it costs
        handover = getattr(gen.networks, "torch_min_batch", None)
        first_torch = (handover is not None and batch >= handover
                       and (not rows or rows[-1]["batch"] < handover))
        if not rows or first_torch or rows[-1]["seconds"] * batch / rows[-1]["batch"] < 2.0:
            run()  # warm-up, when it is cheap
        sync()
        start = time.perf_counter()
        run()
        sync()
        seconds = time.perf_counter() - start
        rows.append({"batch": batch, "seconds": seconds, "motions_per_s": batch / seconds,
                     "peak_mb": _peak_mb(gen.device)})
    return rows


def _peak_mb(device: Any) -> float:
    import torch

    if device.type == "cuda":
        return torch.cuda.max_memory_allocated(device) / 2**20
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


def _free_mb(device: Any) -> float:
    import torch

    if device.type == "cuda":
        return torch.cuda.mem_get_info(device)[0] / 2**20
    with open("/proc/meminfo") as f:
        info = dict(line.split(":", 1) for line in f)
    return int(info["MemAvailable"].split()[0]) / 1024


def run_model(spec: dict[str, Any]) -> dict[str, Any]:
    """One model in one dtype on one backend: AITS per NFE, throughput, part costs, limit."""
    import tempfile

    import torch

    from mlct.eval.aits import time_inference
    from mlct.generate.load import cuda_graph_generator, torch_generator
    from mlct.text import load_text_encoder

    if spec["threads"]:
        torch.set_num_threads(spec["threads"])
    import mlct.generate.backends.onnx.networks as onnx_backend

    if spec.get("one_thread_max_batch") is not None:
        onnx_backend.ONE_THREAD_MAX_BATCH = spec["one_thread_max_batch"]
    if spec.get("torch_min_batch") is not None:
        onnx_backend.TORCH_MIN_BATCH = max(1, spec["torch_min_batch"])
    preset, sampler, nfes = MODELS[spec["model"]]
    bundle = bundle_in_memory(preset, sampler)  # read (or built) once for every generator here
    gen = torch_generator(*bundle, spec["device"], spec["dtype"])
    device = gen.device
    sync = _syncer(device)
    if device.type == "cuda":
        gen.networks._text_encoder = load_text_encoder(gen.meta["text_encoder"], device=device)
    gen.encode_text([""])  # loads the text encoder: loading is not timed
    costs = part_costs(gen)  # the model's, counted on its eager torch modules
    if spec["backend"] == "cuda-graphs":
        gen = cuda_graph_generator(*bundle, spec["device"],
                                   spec["dtype"])  # its text encoder on the GPU, graphed
        gen.encode_text([""])
    elif spec["backend"] == "torch-compiled" and device.type == "cuda":
        _compile_for_cuda(gen)
    if spec["backend"] in ONNX_BACKENDS:
        folder = tempfile.mkdtemp(prefix="mlct-bench-onnx-")
        gen = onnx_generator(preset, sampler, folder, int8=spec["backend"] == "onnx-int8")
        if spec["backend"] == "onnx-int8":  # its step reads int8 weights and their scales
            costs["step"]["bytes"] = float(_graph_weight_bytes(gen.networks.graphs.denoiser))
        if spec["backend"] == "onnx-spinning":  # what a machine of 4 cores or more runs
            gen.networks.spinning = True
        gen.encode_text([""])
    elif spec["backend"] == "torch-compiled" and device.type == "cpu":
        # inductor cannot lower the packed products
        gen = variant(*bundle, "fast", True, dtype=spec["dtype"])
        _compile_for_cpu(gen)
    # The roofs are measured before and after the timings and the better kept: a slow spell of
    # the host during one measurement would otherwise raise the limit and flatter the ratio.
    bandwidth = {part: read_bandwidth(int(c["bytes"]), device) for part, c in costs.items()}
    peak_dtype = spec["dtype"] if device.type == "cpu" else "bfloat16"
    peak = spec["peak_flops"][peak_dtype]
    text_peak = spec["peak_flops"]["float32"]  # the text encoder runs in fp32

    def best(part: str, times: int = 1) -> float:
        c = costs[part]
        roof = text_peak if part == "text" else peak
        return times * max(c["flops"] / roof, c["bytes"] / bandwidth[part]) * 1000.0

    def limits(row: dict[str, Any]) -> dict[str, Any]:
        limit_warm = best("step", row["nfe"]) + best("decode")
        return {"limit_warm_ms": limit_warm, "limit_cold_ms": limit_warm + best("text"),
                "limit_parts_ms": {"text": best("text"), "step": best("step"),
                                   "decode": best("decode")}}

    rows = []
    chosen = spec.get("nfes") or (5, 50) if spec["quick"] else spec.get("nfes") or nfes
    for nfe in [n for n in nfes if n in chosen or n == 50]:  # 50: the LDMs' steps
        if spec["quick"]:
            runs, warmup = 3, 1
        else:  # as many runs as fit the budget, from one probe run
            probe = time_inference(gen, TEXTS, nfe=nfe, runs=1, warmup=1)["aits_ms"]
            runs = max(3, min(spec["runs"], int(spec["aits_budget_s"] * 1000 / probe)))
            warmup = 1 if probe > 500 else 3  # the probe warmed it up already
        t = time_inference(gen, TEXTS, nfe=nfe, runs=runs, warmup=warmup)["median"]
        warm = time_pipeline(gen, nfe, runs, warmup=2)  # what generate() runs
        # at generate()'s default length too: the conv decoder draws only the cells a clip
        # needs (nn/conv_autoencoder.py), so a 5 s clip costs less than 196 frames
        default = time_pipeline(gen, nfe, runs, warmup=2, frames=DEFAULT_FRAMES)
        rows.append({"nfe": nfe, "runs": runs, **t, "warm_ms": warm,
                     "cold_ms": warm - t["text_cached_ms"] + t["text_ms"],
                     "warm_default_ms": default,
                     "cold_default_ms": default - t["text_cached_ms"] + t["text_ms"]})
        print(f"  {spec['model']} {spec['backend']} {spec['dtype']} nfe {nfe}: warm {warm:.1f} ms "
              f"(limit so far {limits(rows[-1])['limit_warm_ms']:.1f} ms)", file=sys.stderr,
              flush=True)
    tput = throughput(gen, spec["throughput_budget_s"], sync)
    bandwidth = {part: max(bandwidth[part], read_bandwidth(int(c["bytes"]), device))
                 for part, c in costs.items()}
    peak = max(peak, peak_matmul_flops(getattr(torch, peak_dtype), device))
    text_peak = max(text_peak, peak_matmul_flops(torch.float32, device)) \
        if peak_dtype != "float32" else peak
    for row in rows:
        row.update(limits(row))
    steps = gen.check_nfe(None)
    for row in tput:  # the batch's limit: FLOPs grow with B, the weights are read once
        if "motions_per_s" in row:
            b = row["batch"]
            limit_s = sum(times * max(b * costs[part]["flops"] / peak,
                                      costs[part]["bytes"] / bandwidth[part])
                          for part, times in (("step", steps), ("decode", 1)))
            row["limit_motions_per_s"] = b / limit_s
    if spec["backend"] in ONNX_BACKENDS:
        import shutil

        shutil.rmtree(folder, ignore_errors=True)
    from mlct.generate.backends.onnx.networks import ONE_THREAD_MAX_BATCH, TORCH_MIN_BATCH

    return {"model": spec["model"], "dtype": spec["dtype"], "backend": spec["backend"],
            "one_thread_max_batch": ONE_THREAD_MAX_BATCH, "torch_min_batch": TORCH_MIN_BATCH,
            "device": str(device), "threads": torch.get_num_threads(), "aits": rows, "throughput": tput,
            "costs": costs, "bandwidth_gb_s": {k: v / 1e9 for k, v in bandwidth.items()},
            "peak_gflop_s": {peak_dtype: peak / 1e9, "float32": text_peak / 1e9}}


def ablations(reps: int, onnx: bool = False) -> list[dict[str, Any]]:
    """Each optimization of the inference path on and off, interleaved run by run so that a
    busy machine disturbs all variants alike: medians at batch 1, 5 NFE, 196 frames, warm text.
    onnx: the onnx backend too (ONNX Runtime's threads follow torch.set_num_threads)."""
    import shutil
    import tempfile

    import numpy as np
    import torch

    from mlct.generate.load import load_onnx, torch_generator

    threads = torch.get_num_threads()
    rows = []
    for model in ("small CM", "paper CM"):
        meta, tensors = bundle_in_memory(*MODELS[model][:2])
        default = torch_generator(meta, tensors)
        variants: list[tuple[str, Any, int]] = [  # name, generator, threads
            ("before: torch layers, conditions every step, no_grad",
             variant(meta, tensors, "torch", False, False), threads),
            ("+ fast layers (SDPA, plain products)",
             variant(meta, tensors, "fast", False, False), threads),
            ("+ weights packed for oneDNN", variant(meta, tensors, "packed", False, False),
             threads),
            ("+ text and time terms once per sample",
             variant(meta, tensors, "packed", True, False), threads),
            ("+ inference_mode (the float32 default)", default, threads),
            ("  the same with bfloat16 products",
             torch_generator(meta, tensors, dtype="bfloat16"), threads)]
        if threads > 1:
            variants.append(("  the float32 default on 1 thread", default, 1))
        if onnx:  # the other backend, interleaved with the rest: a busy machine hits all alike
            folder = tempfile.mkdtemp(prefix="mlct-bench-onnx-")
            onnx_gen = onnx_generator(*MODELS[model][:2], folder)
            variants.append(("  the onnx backend (ONNX Runtime, float32)", onnx_gen, threads))
            if threads > 1:  # ONNX Runtime's threads are set when its sessions are made
                variants.append(("  the onnx backend on 1 thread",
                                 load_onnx(folder, threads=1), 1))
        cond = torch.randn(1, TEXT_DIM, generator=torch.Generator().manual_seed(0))
        cond = cond / cond.norm()
        times = np.zeros((len(variants), reps, 2))
        for rep in range(reps + 2):
            for i, (_, gen, n) in enumerate(variants):
                torch.set_num_threads(n)
                start = time.perf_counter()
                z = gen.sample_latents(cond, 5, seed=rep)
                mid = time.perf_counter()
                gen.decode(z, [FRAMES])
                end = time.perf_counter()
                if rep >= 2:  # two warm-up rounds
                    times[i, rep - 2] = (mid - start, end - mid)
        torch.set_num_threads(threads)
        if onnx:
            shutil.rmtree(folder, ignore_errors=True)
        medians = np.median(times, axis=1) * 1000.0
        before = medians[0].sum()
        for (name, *_), (sampling, decoding) in zip(variants, medians):
            rows.append({"model": model, "variant": name, "sampling_ms": float(sampling),
                         "decoding_ms": float(decoding), "total_ms": float(sampling + decoding),
                         "speedup": float(before / (sampling + decoding))})
    return rows


def print_ablations(rows: list[dict[str, Any]]) -> None:
    print("\nablations: batch 1, 5 NFE, 196 frames, text from the memo; medians in ms")
    print(f"{'model':<9} {'variant':<54} {'sampl':>6} {'decode':>6} {'total':>6} {'gain':>5}")
    for r in rows:
        print(f"{r['model']:<9} {r['variant']:<54} {r['sampling_ms']:>6.1f} "
              f"{r['decoding_ms']:>6.1f} {r['total_ms']:>6.1f} {r['speedup']:>4.2f}x")


def machine(device: str) -> dict[str, Any]:
    import torch

    info: dict[str, Any] = {"torch": torch.__version__, "python": platform.python_version(),
                            "cores": os.cpu_count(), "cpu": platform.processor()}
    try:
        with open("/proc/cpuinfo") as f:
            info["cpu"] = next(line.split(":", 1)[1].strip() for line in f
                               if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    if device == "cuda":
        info["gpu"] = torch.cuda.get_device_name(0)
    return info


def quality_bf16() -> dict[str, float]:
    """Joints of the small CM in bfloat16 against float32: 8 prompts, 196 frames, 5 NFE."""
    import torch

    import mlct
    from mlct.motion.features import recover_from_ric

    out = []
    for dtype in ("float32", "bfloat16"):
        gen = mlct.load(small_model_dir(), dtype=dtype)
        cond = gen.encode_text(TEXTS[:8])
        feats = gen.decode(gen.sample_latents(cond, 5, seed=list(range(8))), [FRAMES] * 8)
        out.append(torch.stack([recover_from_ric(torch.from_numpy(f)) for f in feats]))
    ref, got = out
    dist = (got - ref).norm(dim=-1) * 1000.0
    pose = ((got - got[:, :, :1]) - (ref - ref[:, :, :1])).norm(dim=-1) * 1000.0
    return {"mean_mm": float(dist.mean()), "max_mm": float(dist.max()),
            "pose_mean_mm": float(pose.mean()), "pose_max_mm": float(pose.max())}


def targets(results: list[dict[str, Any]], device: str) -> list[tuple[str, str, bool]]:
    """(target, measured, met) for each of the speed targets (docs/performance.md) this run measured."""
    def row(model: str, kind: tuple[str, str], nfe: int) -> dict[str, Any] | None:
        for r in results:
            if r["model"] == model and (r["backend"], r["dtype"]) == kind:
                return next((a for a in r["aits"] if a["nfe"] == nfe), None)
        return None

    def batch(model: str, kind: tuple[str, str], size: int) -> dict[str, Any] | None:
        for r in results:
            if r["model"] == model and (r["backend"], r["dtype"]) == kind:
                return next((t for t in r["throughput"]
                             if t["batch"] == size and "motions_per_s" in t), None)
        return None

    out = []
    for kind in sorted({(r["backend"], r["dtype"]) for r in results}):
        label = " ".join(kind)  # "torch float32", "onnx float32": the targets' label
        cm, small, ldm = row("paper CM", kind, 5), row("small CM", kind, 5), \
            row("paper LDM", kind, 50)
        small_ldm = row("small LDM", kind, 50)
        if device == "cpu":
            if small:
                out.append((f"small CM {label}: <= 5 ms warm, 5 NFE", f"{small['warm_ms']:.1f} ms",
                            small["warm_ms"] <= 5.0))
                out.append((f"small CM {label}: <= 10 ms cold, 5 NFE", f"{small['cold_ms']:.1f} ms",
                            small["cold_ms"] <= 10.0))
                ratio = small["warm_ms"] / small["limit_warm_ms"]
                out.append((f"small CM {label}: within 3x of the limit (warm)",
                            f"{ratio:.1f}x ({small['limit_warm_ms']:.2f} ms)", ratio <= 3.0))
                ratio = small["cold_ms"] / small["limit_cold_ms"]
                out.append((f"small CM {label}: within 3x of the limit (cold)",
                            f"{ratio:.1f}x ({small['limit_cold_ms']:.2f} ms)", ratio <= 3.0))
            if cm:
                out.append((f"paper CM {label}: <= 40 ms warm, 5 NFE",
                            f"{cm['warm_ms']:.1f} ms (cold {cm['cold_ms']:.1f})",
                            cm["warm_ms"] <= 40.0))
            for name in ("small CM", "paper CM"):
                b = batch(name, kind, 64)
                if b and "limit_motions_per_s" in b:
                    ratio = b["limit_motions_per_s"] / b["motions_per_s"]
                    out.append((f"{name} {label}: batch 64 within 2x of its limit",
                                f"{b['motions_per_s']:.0f}/s, limit "
                                f"{b['limit_motions_per_s']:.0f}/s: {ratio:.1f}x", ratio <= 2.0))
        else:  # a new sentence: the text encoder runs (cold); warm in brackets
            if small:
                out.append((f"small CM {label}: <= 3 ms per sentence, 5 NFE",
                            f"{small['cold_ms']:.2f} ms (warm {small['warm_ms']:.2f})",
                            small["cold_ms"] <= 3.0))
            rates = [t["motions_per_s"] for r in results
                     if r["model"] == "small CM" and (r["backend"], r["dtype"]) == kind
                     for t in r["throughput"] if "motions_per_s" in t]
            if rates:
                out.append((f"small CM {label}: >= 50,000 motions/s batched",
                            f"{max(rates):,.0f}/s", max(rates) >= 50000))
        for size, c, l in (("paper", cm, ldm), ("small", small, small_ldm)):
            if c and l:
                ratio = l["warm_ms"] / c["warm_ms"]
                cold = l["cold_ms"] / c["cold_ms"]
                out.append((f"{size} LDM (50 steps) / {size} CM {label}: >= 8x",
                            f"{ratio:.1f}x (cold {cold:.1f}x)", ratio >= 8.0))
    return out


def report(results: list[dict[str, Any]], info: dict[str, Any], device: str) -> None:
    print(f"\nmachine: {info['cpu']}, {info['cores']} cores"
          + (f", {info['gpu']}" if "gpu" in info else "") + f"; torch {info['torch']}; "
          f"peak matmul " + ", ".join(f"{k} {v / 1e9:.0f} GFLOP/s"
                                      for k, v in info["peak_flops"].items()))
    onnx = [r for r in results if r["backend"].startswith("onnx")]
    if onnx:
        print(f"onnx backends: batches up to {onnx[0]['one_thread_max_batch']} run the sampler "
              f"graph on one thread (ONE_THREAD_MAX_BATCH); "
              + (f"batches of {onnx[0]['torch_min_batch']} or more are run by the torch networks"
                 if onnx[0].get("torch_min_batch") else "no batch is handed to the torch networks")
              + " (TORCH_MIN_BATCH)")
    print("\nAITS at batch 1, 196 frames, medians in ms (warm: text from the memo; cold: "
          "encoder run; limit / c.lim: the warm / cold limits)")
    head = (f"{'model':<10} {'backend':<14} {'dtype':<8} {'NFE':>3} {'text':>6} {'sampl':>7} {'decode':>6} "
            f"{'warm':>7} {'cold':>7} {'limit':>6} {'x lim':>5} {'c.lim':>6} {'x lim':>5}")
    print(head)
    print("-" * len(head))
    for r in results:
        for a in r["aits"]:
            print(f"{r['model']:<10} {r['backend']:<14} {r['dtype']:<8} {a['nfe']:>3} "
                  f"{a['text_ms']:>6.1f} "
                  f"{a['sampling_ms']:>7.1f} {a['decoding_ms']:>6.1f} {a['warm_ms']:>7.1f} "
                  f"{a['cold_ms']:>7.1f} {a['limit_warm_ms']:>6.2f} "
                  f"{a['warm_ms'] / a['limit_warm_ms']:>5.1f} {a['limit_cold_ms']:>6.2f} "
                  f"{a['cold_ms'] / a['limit_cold_ms']:>5.1f}")
    print(f"\nthe same at generate()'s default length ({DEFAULT_FRAMES} frames), warm / cold ms: "
          + "; ".join(f"{r['model']} {r['backend']} {r['dtype']} NFE {a['nfe']}: "
                      f"{a['warm_default_ms']:.1f} / {a['cold_default_ms']:.1f}"
                      for r in results for a in r["aits"] if "warm_default_ms" in a))
    by = {(r["model"], r["backend"], r["dtype"]): r for r in results}
    for size in ("paper", "small"):
        for backend, dtype in sorted({(r["backend"], r["dtype"]) for r in results}):
            cm = by.get((f"{size} CM", backend, dtype))
            ldm = by.get((f"{size} LDM", backend, dtype))
            if cm and ldm:
                base = ldm["aits"][0]
                ratios = ", ".join(f"NFE {a['nfe']} {base['warm_ms'] / a['warm_ms']:.1f}x"
                                   for a in cm["aits"])
                print(f"{size} LDM (50 DDIM + CFG) / {size} CM, {backend} {dtype}, warm: "
                      f"{ratios}")
    print("\nthroughput: sampling + decoding at the default NFE, 196 frames; (limit/s, limit / "
          "measured)")
    for r in results:
        cells = [f"B={t['batch']}: {t['motions_per_s']:.1f}/s ({t['limit_motions_per_s']:.0f}/s, "
                 f"{t['limit_motions_per_s'] / t['motions_per_s']:.1f}x), "
                 f"peak {t['peak_mb']:.0f} MB"
                 if "motions_per_s" in t else f"B={t['batch']}: skipped ({t['skipped']})"
                 for t in r["throughput"]]
        print(f"{r['model']:<10} {r['backend']:<14} {r['dtype']:<8} " + "; ".join(cells))
    print("\nlimit parts (ms at batch 1): text / one step / decoding; FLOPs and weight MB")
    for r in results:
        a, c = r["aits"][0]["limit_parts_ms"], r["costs"]
        print(f"{r['model']:<10} {r['backend']:<14} {r['dtype']:<8} {a['text']:.2f} / "
              f"{a['step']:.3f} / "
              f"{a['decode']:.2f} ms; " + ", ".join(
                  f"{k} {v['flops'] / 1e9:.3f} GFLOP {v['bytes'] / 2**20:.1f} MB "
                  f"@ {r['bandwidth_gb_s'][k]:.0f} GB/s" for k, v in c.items()))
    if "quality_bf16" in info:
        q = info["quality_bf16"]
        print(f"\nbfloat16 vs float32 joints (bundled model): mean {q['mean_mm']:.1f} mm, max "
              f"{q['max_mm']:.1f} mm; relative to the root: mean {q['pose_mean_mm']:.2f} mm, "
              f"max {q['pose_max_mm']:.1f} mm")
    print("\ntargets")
    for name, measured, met in targets(results, device):
        print(f"  {'met    ' if met else 'NOT met'}  {name}: {measured}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a ~30 s smoke run")
    parser.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    parser.add_argument("--dtypes", default=None,
                        help="comma-separated: float32,bfloat16 (default: both on CPU, "
                             "bfloat16 on CUDA; --quick: float32)")
    parser.add_argument("--models", default=",".join(MODELS),
                        help=f"comma-separated, of: {', '.join(MODELS)}")
    parser.add_argument("--backends", default=None,
                        help="comma-separated, of: " + ", ".join(BACKENDS) + " (default: all "
                             "that can run here but torch-compiled, whose compilation takes "
                             "minutes; the onnx ones run on the CPU only)")
    parser.add_argument("--threads", type=int, default=0, help="intra-op threads (0: torch's)")
    parser.add_argument("--one-thread-max-batch", type=int, default=None, metavar="B",
                        help="onnx backends: batches up to B run the sampler graph on one thread "
                             "(default: the backend's ONE_THREAD_MAX_BATCH; 0: never)")
    parser.add_argument("--torch-min-batch", type=int, default=None, metavar="B",
                        help="onnx backends: batches of B (>= 1) or more are run by the torch "
                             "networks (default: the backend's TORCH_MIN_BATCH)")
    parser.add_argument("--runs", type=int, default=20, help="timed runs per AITS figure (at "
                        "most; fewer where a run is slow)")
    parser.add_argument("--json", default=None, help="write every figure to this file")
    parser.add_argument("--nfes", default=None,
                        help="comma-separated NFEs of the consistency models (default 1,3,5,10; "
                             "--quick: 5); the LDMs always take 50 steps")
    parser.add_argument("--throughput-budget", type=float, default=0.0,
                        help="seconds a throughput size may take (default 15; --quick: 1)")
    parser.add_argument("--ablations", type=int, default=0, metavar="REPS",
                        help="instead: each optimization on and off, REPS interleaved runs")
    parser.add_argument("--small-model", default=None, metavar="DIR",
                        help="the bundle timed as the small CM (default: the bundled model), to "
                             "time a candidate before it is shipped")
    parser.add_argument("--headline", action="store_true",
                        help="only the headline figures (above): generate()'s defaults, one "
                             "sample warm and cold")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--headline-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.headline_child:
        print(json.dumps(headline(args.runs if args.runs != 20 else 30)))
        return
    head = run_headline(args.runs if args.runs != 20 else 30)
    print_headline(head)
    if args.headline:
        if args.json:
            _write_json(args.json, {"headline": head})
        return
    if args.small_model:  # children read it too: each model is timed in its own process
        os.environ[SMALL_MODEL_ENV] = str(Path(args.small_model).resolve())
    if args.child:
        print(json.dumps(run_model(json.loads(args.child))))
        return
    import torch

    models = [m.strip() for m in args.models.split(",")]
    unknown = [m for m in models if m not in MODELS]
    if unknown:
        parser.error(f"unknown model {unknown[0]!r}; choose from {', '.join(MODELS)}")
    if args.device == "cuda" and not torch.cuda.is_available():
        parser.error("--device cuda: no CUDA device here")
    default = "bfloat16" if args.device == "cuda" else (
        "float32" if args.quick else "float32,bfloat16")
    dtypes = (args.dtypes or default).split(",")
    backends = _backends(args.backends, args.device, parser)
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.ablations:
        rows = ablations(args.ablations, onnx="onnx" in backends)
        print_ablations(rows)
        if args.json:
            _write_json(args.json, {"machine": machine("cpu"), "ablations": rows})
        return
    dev = torch.device(args.device)
    info = machine(args.device)
    info["threads"] = torch.get_num_threads()
    info["peak_flops"] = {d: peak_matmul_flops(getattr(torch, d), dev)
                          for d in sorted({"float32", "bfloat16"})}
    results = []
    for backend, dtype in [(b, d) for b in backends for d in dtypes
                           if not b.startswith("onnx") or d == "float32"]:
        for model in models:
            print(f"measuring {model} ({backend}, {dtype}) ...", file=sys.stderr, flush=True)
            spec = {"model": model, "dtype": dtype, "backend": backend, "device": args.device,
                    "threads": args.threads, "quick": args.quick, "runs": args.runs,
                    "one_thread_max_batch": args.one_thread_max_batch,
                    "torch_min_batch": args.torch_min_batch,
                    "aits_budget_s": 20.0,
                    "throughput_budget_s": args.throughput_budget or (
                        1.0 if args.quick else 15.0),
                    "nfes": [int(n) for n in args.nfes.split(",")] if args.nfes else None,
                    "peak_flops": info["peak_flops"]}
            proc = subprocess.run([sys.executable, __file__, "--child", json.dumps(spec)],
                                  stdout=subprocess.PIPE, text=True, check=False)
            if proc.returncode != 0:
                sys.exit(f"{model} ({backend}, {dtype}) failed (exit {proc.returncode})")
            results.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    if "bfloat16" in dtypes and args.device == "cpu":
        info["quality_bf16"] = quality_bf16()
    report(results, info, args.device)
    print_headline(head)
    if args.json:
        _write_json(args.json, {"machine": info, "results": results, "headline": head})


def headline(runs: int) -> dict[str, Any]:
    """The headline figures (module docstring), in this process: medians in ms."""
    import mlct

    gen = mlct.load()
    frames = gen.frames_for(5.0)
    seen = gen.encode_text([HEADLINE_PROMPT])  # in the memo from here on
    for i in range(3):  # warm-up: the sampler graphs are built at a step count's second call
        gen.generate(HEADLINE_PROMPT, seconds=5, seed=i)
        gen.sample_features(seen, None, [i], None, [frames])
    times: dict[str, list[float]] = {"generate": [], "warm": [], "cold": []}
    encoder = gen.text_encoder
    for i in range(runs):
        t0 = time.perf_counter()
        gen.generate(HEADLINE_PROMPT, seconds=5, seed=i)
        t1 = time.perf_counter()
        gen.sample_features(gen.encode_text([HEADLINE_PROMPT]), None, [i], None, [frames])
        t2 = time.perf_counter()
        text = TEXTS[i % len(TEXTS)]
        new = (encoder.encode_numpy([text]) if getattr(gen.networks, "numpy", False)
               else encoder.encode([text]).float())  # not memoized: the encoder runs
        gen.sample_features(new, None, [i], None, [frames])
        t3 = time.perf_counter()
        times["generate"].append(t1 - t0)
        times["warm"].append(t2 - t1)
        times["cold"].append(t3 - t2)
    return {"backend": gen.backend_note, "frames": frames, "nfe": gen.default_nfe,
            "candidates": gen.candidates, "runs": runs,
            "torch_imported": "torch" in sys.modules, "threads": gen.networks.threads
            if hasattr(gen.networks, "threads") else None,
            **{k: 1000.0 * statistics.median(v) for k, v in times.items()}}


def run_headline(runs: int) -> dict[str, Any]:
    """headline() in a fresh process (what a user's first process runs: no torch loaded)."""
    proc = subprocess.run([sys.executable, __file__, "--headline-child", "--runs", str(runs)],
                          stdout=subprocess.PIPE, text=True, check=False)
    if proc.returncode != 0:
        sys.exit(f"the headline failed (exit {proc.returncode})")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def print_headline(head: dict[str, Any]) -> None:
    def verdict(key: str) -> str:
        target = HEADLINE_TARGETS_MS[key]
        return f"{head[key]:.1f} ms ({'meets' if head[key] <= target else 'MISSES'} <= {target:g})"

    print(f"headline on {head['backend']}, {head['threads']} threads, torch imported: "
          f"{'yes' if head['torch_imported'] else 'no'}; medians of {head['runs']}:")
    print(f"  generate() with its defaults (best of {head['candidates']}, {head['nfe']} NFE), "
          f"a 5 s motion of a sentence seen before: {verdict('generate')}")
    print(f"  one sample, {head['frames']} frames, {head['nfe']} NFE: warm {verdict('warm')}, "
          f"cold (+ the text encoder on a new sentence) {verdict('cold')}")


BACKENDS = ("torch", "torch-compiled", "onnx", "onnx-spinning", "onnx-int8", "cuda-graphs")
ONNX_BACKENDS = ("onnx", "onnx-spinning", "onnx-int8")


def _backends(text: str | None, device: str, parser: argparse.ArgumentParser) -> list[str]:
    """The backends to measure: --backends, or all of BACKENDS that can run here (the onnx
    ones on the CPU with onnxruntime installed)."""
    import importlib.util

    installed = importlib.util.find_spec("onnxruntime") is not None
    if text is None:  # torch-compiled only when asked: minutes of compiling per model and size
        return [b for b in BACKENDS if b != "torch-compiled"
                and (not b.startswith("onnx") or (installed and device == "cpu"))
                and (b != "cuda-graphs" or device == "cuda")]
    backends = [b.strip() for b in text.split(",") if b.strip()]
    for backend in backends:
        if backend not in BACKENDS:
            parser.error(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    if any(b.startswith("onnx") for b in backends) and (device != "cpu" or not installed):
        parser.error("--backends onnx: runs on the CPU, with onnxruntime installed "
                     "(pip install onnxruntime==1.32.0)")
    if "cuda-graphs" in backends and device != "cuda":
        parser.error("--backends cuda-graphs: runs on a GPU (--device cuda)")
    return backends


def _write_json(path: str, data: dict[str, Any]) -> None:
    from mlct.io import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps({**data, "command": " ".join(sys.argv)}, indent=2) + "\n")


if __name__ == "__main__":
    main()
