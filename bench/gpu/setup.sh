# Sourced by the GPU scripts (bench/gpu/*.sh, tools/make_broad_model_gpu.sh) on a lent machine
# with no package registry: installs what CARRY_DIR ($1, made by bench/gpu/carry.sh) holds into
# /tmp/mlct_site, restores the shipped MiniLM's float32 weights where bench/gpu/slim.sh left
# them behind, and puts the site and this checkout's src/ and tests/ on PYTHONPATH.
carry=${1:-.devcarry}
site=/tmp/mlct_site
minilm=src/mlct/assets/minilm/model.safetensors
if [ -d "$carry" ]; then
    python3 -c "import pydantic" 2>/dev/null || python3 -m pip install -q --no-index --no-deps \
        --no-compile --no-cache-dir --target "$site" "$carry"/whl/*.whl || exit 1
    if [ ! -f "$minilm" ]; then
        xz -dc "$carry/minilm_fp16.safetensors.xz" > /tmp/minilm_fp16.safetensors || exit 1
        python3 - "$minilm" <<'PY' || exit 1
import sys
from safetensors.torch import load_file, save_file
weights = load_file("/tmp/minilm_fp16.safetensors")
save_file({k: v.float() if v.is_floating_point() else v for k, v in weights.items()}, sys.argv[1])
PY
    fi
fi
export PYTHONPATH="$PWD/src:$PWD/tests:$site${PYTHONPATH:+:$PYTHONPATH}"
# the `mlct` command the recipes call, for this checkout (nothing is pip-installed there)
mkdir -p /tmp/mlct_bin
printf '#!/bin/sh\nexec python3 -m mlct.cli "$@"\n' > /tmp/mlct_bin/mlct
chmod +x /tmp/mlct_bin/mlct
export PATH="/tmp/mlct_bin:$PATH"
OUT=${OUT:-/tmp/gpu_check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
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
