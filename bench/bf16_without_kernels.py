"""Why a generator runs float32 where the CPU has no bfloat16 kernels (mlct/cpu_features.py).

    python bench/bf16_without_kernels.py      # about a minute

Each configuration runs in its own process (oneDNN and ATen read their instruction-set limits
once): this CPU's own kernels, and oneDNN and ATen held to AVX2 (ONEDNN_MAX_CPU_ISA=AVX2
ATEN_CPU_CAPABILITY=avx2: what an AVX2-only x86-64 runs). In each, the torch backend at one
thread makes three 4-s motions (one batch) in float32 and in bfloat16 on the layers as they
run there (held to AVX2: PyTorch's plain kernels, oneDNN refusing bfloat16), best of 7; prints
the time and the mean joint distance from this CPU's float32 motions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PROMPTS = ["a person walks forward", "a person jumps up and down",
           "a person waves with the right hand"]
CONFIGS = {"this CPU's kernels": {}, "held to AVX2": {"ONEDNN_MAX_CPU_ISA": "AVX2",
                                                      "ATEN_CPU_CAPABILITY": "avx2"}}


def measure(dtype: str, out: str) -> None:
    """In the child: time `dtype` on the layers as they run here, bypassing the fallback."""
    import numpy as np
    import torch

    from mlct import cpu_features
    from mlct.generate.load import load_torch
    from mlct.generate.bundle import bundled_model_dir

    torch.set_num_threads(1)
    gen = load_torch(bundled_model_dir(), "cpu", dtype)  # as asked: no fallback
    gen.generate(PROMPTS[0], seconds=4, seed=0)
    times = []
    for _ in range(7):
        start = time.perf_counter()
        motions = gen.generate(PROMPTS, seconds=4, seed=0)
        times.append(time.perf_counter() - start)
    np.save(out, np.stack([m.joints for m in motions]))
    print(json.dumps({"seconds": min(times), "bf16_kernels": cpu_features.onednn_bf16()}))


def main() -> None:
    import numpy as np

    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for name, env in CONFIGS.items():
            for dtype in ("float32", "bfloat16"):
                out = str(Path(tmp) / f"{len(results)}.npy")
                done = subprocess.run([sys.executable, __file__, dtype, out], text=True,
                                      capture_output=True, env={**os.environ, **env}, check=True)
                results[name, dtype] = (json.loads(done.stdout.splitlines()[-1]), np.load(out))
        reference = results["this CPU's kernels", "float32"][1]
        for (name, dtype), (row, joints) in results.items():
            gap = np.linalg.norm(joints - reference, axis=-1).mean() * 1000
            print(f"{name} (oneDNN bf16 kernels: {row['bf16_kernels']}), {dtype}: "
                  f"{row['seconds']:.3f} s, joints {gap:.1f} mm from float32's")


if __name__ == "__main__":
    if len(sys.argv) == 3:
        measure(sys.argv[1], sys.argv[2])
    else:
        main()
