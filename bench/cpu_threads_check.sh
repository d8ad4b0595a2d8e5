#!/usr/bin/env bash
# The onnx and torch backends on more CPU threads than this project's 2-vCPU hosts have: the
# thread counts (ONNX Runtime's intra-op threads per graph, the spinning rules of onnx_io.py)
# were chosen on 2 cores, and a machine of 16 (the lent GPU machines' host) may want fewer
# threads per graph at batch 1 than it has. One quick bench per thread count, the bundled
# model, batch 1 and small batches, warm and cold; runs in ~4 min where the packages are there
# (`bash bench/cpu_threads_check.sh [CARRY_DIR]`, as bench/gpu_check.sh; on a lent machine it
# fits one device call next to nothing else).
set -u
cd "$(dirname "$0")/.."
source bench/gpu_setup.sh "${1:-.devcarry}"
nproc | tee "$OUT/cpus.txt"
for threads in 1 2 4 8 16; do
    step "threads_$threads" 100 python3 bench/inference_speed.py --quick --models "small CM" \
        --backends onnx,torch --dtypes float32 --threads "$threads" \
        --json "$OUT/threads_$threads.json"
done
