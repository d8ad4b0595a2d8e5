"""One stage-2 training step of the `small` preset on the CPU, with PyTorch's dropout and
for-loop AdamW (before 2026-11-28) against the CPU kernels the trainer now picks
(mlct.nn.dropout.CheapDropout's PCG64 masks, fused AdamW), each alone and both; one process,
the variants taking turns step by step so a busy machine hits all alike.

    python bench/train_cpu_kernels.py [--steps 12] [--threads 2] [--precision bf16|fp32]

Batch 64 of synthetic latents and text vectors of the real shapes (the consistency loss, the
backward pass, clipping and the update: what `mlct train cm` runs per step, without the data
loader and the frozen encoder). Prints the median ms per step and the gain over the first row.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch


def make_step(cheap_dropout: bool, fused: bool, precision: str):
    from mlct.config import load_config
    from mlct.diffusion.losses import consistency_training_loss
    from mlct.diffusion.parameterization import ConsistencyFunction
    from mlct.diffusion.schedule import karras_time_grid
    from mlct.nn.build import build_denoiser
    from mlct.nn.dropout import use_cheap_dropout
    from mlct.train.stages import schedule_of

    torch.manual_seed(0)
    config = load_config("small")
    model = build_denoiser(config, 384)
    if cheap_dropout:
        use_cheap_dropout(model)
    n, d = config.ae.n_tokens, config.ae.latent_dim
    x0, cond, null = torch.randn(64, n, d), torch.randn(64, 384), torch.zeros(384)
    schedule, s = schedule_of(config), config.schedule
    online = ConsistencyFunction(model, s.eta, s.time_scale)
    grid = karras_time_grid(s.num_steps, s.eps, s.t_max, s.rho)
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4, fused=True if fused else None)
    model.train()

    def step() -> None:
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=precision == "bf16"):
            loss = consistency_training_loss(online, online, x0, cond, null, schedule, grid,
                                             guidance=1.0)["loss"]
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        optimizer.step()

    return step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=12)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--precision", default="bf16", choices=["bf16", "fp32"])
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    variants = {"torch dropout, for-loop AdamW (before)": make_step(False, False, args.precision),
                "PCG64 dropout": make_step(True, False, args.precision),
                "fused AdamW": make_step(False, True, args.precision),
                "both (the trainer on a CPU now)": make_step(True, True, args.precision)}
    for step in variants.values():
        step(), step()  # warm-up
    times: dict[str, list[float]] = {name: [] for name in variants}
    for _ in range(args.steps):
        for name, step in variants.items():
            start = time.perf_counter()
            step()
            times[name].append(time.perf_counter() - start)
    print(f"stage 2, small preset, batch 64, {args.precision}, {args.threads} threads, "
          f"{args.steps} steps each in turn; median ms per step")
    first = None
    for name, values in times.items():
        median = statistics.median(values) * 1000.0
        first = first or median
        print(f"  {name:40} {median:7.1f} ms  {first / median:4.2f}x")


if __name__ == "__main__":
    main()
