#!/usr/bin/env bash
# Issue 14 (item 5) on a lent GPU: the real trainer (`mlct train ae|cm`) at the paper's sizes
# (config humanml3d: the skip-transformer autoencoder 7 x 256, the denoiser 11 x 512), bfloat16
# autocast (train.*.precision=auto on CUDA), the batches made by DataLoader workers, and how busy
# it keeps the GPU: nvidia-smi's utilization sampled every 200 ms while each stage trains.
#
#   bash bench/gpu_train_check.sh [CARRY_DIR] [WORKERS] [BATCH] [AE_STEPS] [CM_STEPS]
#   (defaults .devcarry 8 64 600 800; logs to $OUT, see gpu_check.sh)
set -u
cd "$(dirname "$0")/.."
source bench/gpu_setup.sh "${1:-.devcarry}"
workers=${2:-8}
batch=${3:-64}
ae_steps=${4:-600}
cm_steps=${5:-800}
data=/tmp/gpu_train_data
run=/tmp/gpu_train_run
busy() {  # name, seconds, command...: step() with the GPU's utilization sampled meanwhile
    local name=$1
    nvidia-smi --query-gpu=utilization.gpu --format=csv,noheader,nounits -lms 200 \
        > "$OUT/$name.util" &
    local sampler=$!
    step "$@"
    kill "$sampler"
}
step synth 150 python3 -m mlct.cli data synth --out "$data" --num 600 --seed 0 --workers 16 --quiet
common=(--data "$data" --out "$run" --config humanml3d --device cuda --quiet
        "data.num_workers=$workers")
busy ae 150 python3 -m mlct.cli train ae "${common[@]}" "train.ae.max_steps=$ae_steps" \
    "train.ae.batch_size=$batch" train.ae.log_every=50 train.ae.val_every=100000 \
    "train.ae.ckpt_every=$ae_steps"
busy cm 150 python3 -m mlct.cli train cm "${common[@]}" "train.cm.max_steps=$cm_steps" \
    "train.cm.batch_size=$batch" train.cm.log_every=50 train.cm.val_every=100000 \
    "train.cm.ckpt_every=$cm_steps"
python3 - "$OUT" "$run" "$batch" <<'PY' | tee "$OUT/summary.txt"
import json, statistics, sys
from pathlib import Path
out, run = Path(sys.argv[1]), Path(sys.argv[2])
for stage in ("ae", "cm"):
    util = [int(v) for v in (out / f"{stage}.util").read_text().split() if v.strip().isdigit()]
    log = run / stage / "log.jsonl"
    rows = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    rates = [r["samples_per_s"] for r in rows[1:] if "samples_per_s" in r]
    # the middle of the run: the start (imports, data, text cache) and the end (checkpoint) out
    middle = util[len(util) // 4 : len(util) - len(util) // 10] if util else []
    print(f"{stage}: batch {sys.argv[3]}, steps {rows[-1]['step'] if rows else 0}, samples/s median "
          f"{statistics.median(rates) if rates else float('nan'):.0f}; GPU utilization "
          f"{len(util)} samples, mean {statistics.mean(util) if util else float('nan'):.0f}%, "
          f"middle half median {statistics.median(middle) if middle else float('nan'):.0f}%, "
          f"middle mean {statistics.mean(middle) if middle else float('nan'):.0f}%")
PY
