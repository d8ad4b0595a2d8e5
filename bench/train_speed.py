"""Training throughput (samples/s) and peak memory of each stage, at preset sizes.

    python bench/train_speed.py [--presets small humanml3d] [--stages ae cm diffusion]
                                [--steps 5] [--device cpu|cuda] [--precision auto fp32 bf16]

A preset may carry config overrides after colons, to time a size no preset has beside one that
does: `--presets small small:denoiser.width=192:denoiser.layers=3` (the skip transformer
needs an odd layer count).

Each (preset, stage) runs in its own process on synthetic batches of the real shapes (motion
crops of 196 frames, 263-d features, 384-d text embeddings), so the figures are the model's and
the optimizer's, not the disk's. Peak memory: the process's max RSS on CPU, the allocator's
peak on CUDA. One warm-up step is not timed. --precision as train.*.precision ('auto': bf16
autocast on CUDA, float32 on CPU); several values time each one and print the ratios to the
first, in the same run (on a CPU with avx512_bf16, bf16 autocast is the recipe's choice).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any


def build_step(preset: str, stage: str, device: str, precision: str,
               cheap_dropout: bool | None = None, fused_adamw: bool | None = None
               ) -> tuple[Callable[[], None], Any, int, bool]:
    """(one training step, the trained module, batch size, bf16 autocast?) of a stage at a
    preset's sizes, on synthetic batches of the real shapes. The optimizer and CPU kernels are
    the trainer's (train/loop.py prepare_training) unless cheap_dropout / fused_adamw name a
    variant to compare."""
    import torch

    from mlct.config import load_config
    from mlct.diffusion.losses import consistency_training_loss, diffusion_training_loss
    from mlct.diffusion.parameterization import ConsistencyFunction
    from mlct.diffusion.schedule import karras_time_grid
    from mlct.nn.build import build_autoencoder, build_denoiser
    from mlct.nn.dropout import use_cheap_dropout
    from mlct.train.loop import prepare_training
    from mlct.train.stages import AutoencoderStage, schedule_of

    torch.manual_seed(0)
    dev = torch.device(device)
    name, *overrides = preset.split(":")
    config = load_config(name, overrides)
    tc = getattr(config.train, stage)
    batch = tc.batch_size
    text_dim, feature_dim, frames = 384, 263, 196
    if stage == "ae":
        ae_stage = AutoencoderStage(config, dev, torch.zeros(feature_dim), torch.ones(feature_dim),
                                    "humanml3d")
        model = ae_stage.model
        lengths = torch.randint(40, frames + 1, (batch,))
        lengths[0] = frames
        data = {"motion": torch.randn(batch, frames, feature_dim) * 0.5, "length": lengths}

        def step_loss():
            return ae_stage.loss(model, data)["loss"]
    else:
        ae = build_autoencoder(config, feature_dim).to(dev).eval().requires_grad_(False)
        model = build_denoiser(config, text_dim).to(dev)
        n, d = config.ae.n_tokens, config.ae.latent_dim
        motion = torch.randn(batch, frames, feature_dim, device=dev) * 0.5
        lengths = torch.full((batch,), frames, device=dev)
        cond = torch.randn(batch, text_dim, device=dev)
        null = torch.zeros(text_dim, device=dev)
        schedule = schedule_of(config)
        if stage == "cm":
            s = config.schedule
            online = ConsistencyFunction(model, s.eta, s.time_scale)
            target = ConsistencyFunction(build_denoiser(config, text_dim).to(dev).eval(),
                                         s.eta, s.time_scale).requires_grad_(False)
            grid = karras_time_grid(s.num_steps, s.eps, s.t_max, s.rho, device=dev)

            def step_loss():
                with torch.no_grad():  # the frozen AE encodes each batch, as in training
                    x0 = ae.encode(motion, lengths).z
                return consistency_training_loss(online, target, x0, cond, null, schedule,
                                                 grid, guidance=1.0)["loss"]
        else:
            def step_loss():
                with torch.no_grad():
                    x0 = ae.encode(motion, lengths).z
                return diffusion_training_loss(model, x0, cond, null, schedule)["loss"]
        assert (n, d) == ae.latent_shape
    if cheap_dropout is None and fused_adamw is None:
        optimizer = prepare_training(model, 1e-4, 0.0, dev)  # the trainer's choices
    else:
        if cheap_dropout:
            use_cheap_dropout(model)
        optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4,
                                      fused=True if fused_adamw else None)
    use_bf16 = precision == "bf16" or (precision == "auto" and dev.type == "cuda")

    def one_step():
        with torch.autocast(dev.type, dtype=torch.bfloat16, enabled=use_bf16):
            loss = step_loss()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        optimizer.step()

    return one_step, model, batch, use_bf16


def _run_one(preset: str, stage: str, steps: int, device: str, precision: str) -> dict:
    import torch

    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    one_step, model, batch, use_bf16 = build_step(preset, stage, device, precision)
    dev = torch.device(device)
    one_step()  # warm-up
    if dev.type == "cuda":
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
    start = time.perf_counter()
    for _ in range(steps):
        one_step()
    if dev.type == "cuda":
        torch.cuda.synchronize()
    seconds = (time.perf_counter() - start) / steps
    if dev.type == "cuda":
        peak_mb = torch.cuda.max_memory_allocated() / 2**20
    else:  # ru_maxrss is in KiB on Linux
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    params = sum(p.numel() for p in model.parameters())
    return {"preset": preset, "stage": stage, "batch": batch, "params_m": params / 1e6,
            "s_per_step": seconds, "samples_per_s": batch / seconds, "peak_mb": peak_mb,
            "rss_before_mb": rss_before / 1024, "threads": torch.get_num_threads(),
            "device": device, "precision": "bf16" if use_bf16 else "fp32"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["small", "humanml3d"])
    parser.add_argument("--stages", nargs="+", default=["ae", "cm", "diffusion"])
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--precision", nargs="+", default=["auto"],
                        choices=["auto", "fp32", "bf16"])
    parser.add_argument("--one", nargs=3, help=argparse.SUPPRESS)  # child process
    args = parser.parse_args()
    if args.one:
        print(json.dumps(_run_one(args.one[0], args.one[1], args.steps, args.device,
                                  args.one[2])))
        return
    rows = []
    for preset in args.presets:
        for stage in args.stages:
            first = None
            for precision in args.precision:
                out = subprocess.run([sys.executable, __file__, "--one", preset, stage,
                                      precision, "--steps", str(args.steps), "--device",
                                      args.device], capture_output=True, text=True, check=True)
                r = json.loads(out.stdout.strip().splitlines()[-1])
                first = first or r
                ratio = (f"  {r['samples_per_s'] / first['samples_per_s']:.2f}x {first['precision']}"
                         if r is not first else "")
                print(f"{r['preset']:>10} {r['stage']:>9}  batch {r['batch']:>3}  "
                      f"{r['params_m']:6.2f} M params  {r['s_per_step']:7.3f} s/step  "
                      f"{r['samples_per_s']:8.1f} samples/s  peak {r['peak_mb']:7.0f} MB  "
                      f"({r['device']}, {r['threads']} threads, {r['precision']}){ratio}",
                      flush=True)
                if precision == args.precision[0]:
                    rows.append(r)
    by = {(r["preset"], r["stage"]): r for r in rows}
    first_preset = args.presets[0]
    for stage in args.stages:
        for preset in args.presets[1:]:
            if (first_preset, stage) in by and (preset, stage) in by:
                ratio = by[(preset, stage)]["samples_per_s"] / by[(first_preset, stage)]["samples_per_s"]
                print(f"{stage}: {preset} trains {ratio:.2f}x the samples/s of {first_preset}")


if __name__ == "__main__":
    main()
