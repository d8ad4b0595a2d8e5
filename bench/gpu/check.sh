#!/usr/bin/env bash
# The GPU checks in one run, for a machine lent for minutes with no package registry:
# the cuda-graphs backend's parity tests, then bench/inference_speed.py on the GPU (the bundled
# model on the torch and cuda-graphs backends; the paper-size networks on cuda-graphs).
#
#   bash bench/gpu/check.sh [CARRY_DIR]    # writes its logs and JSON to $OUT (default /tmp/gpu_check)
#
# CARRY_DIR (default .devcarry) holds what such a machine lacks: whl/ (pydantic and its three
# wheels, cp312) and minilm_fp16.safetensors.xz (the shipped MiniLM's weights in float16, to
# fit a 64 MiB transfer with bench/gpu/slim.sh; restored to float32 there: the timings do not
# depend on the values, the parity tests compare the backends on the same weights).
# `bash bench/gpu/carry.sh` makes it. Where the packages are installed already, CARRY_DIR may
# be absent.
set -u
cd "$(dirname "$0")/../.."
source bench/gpu/setup.sh "${1:-.devcarry}"
step pytest 120 python3 -m pytest -q -p no:cacheprovider tests/test_cuda_graphs.py
step small 200 python3 bench/inference_speed.py --device cuda --models "small CM" --nfes 1,5 \
    --dtypes bfloat16,float32 \
    --backends torch,cuda-graphs --runs 30 --throughput-budget 4 --json "$OUT/small.json"
step paper 120 python3 bench/inference_speed.py --device cuda --models "paper CM,paper LDM" \
    --nfes 5 --backends cuda-graphs --runs 20 --throughput-budget 2 --json "$OUT/paper.json"
step parts 90 python3 bench/gpu/throughput_parts.py --batches 4096,16384
