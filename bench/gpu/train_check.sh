#!/usr/bin/env bash
# On a lent GPU: the real trainer (`mlct train ae|cm`) at the paper's sizes
# (config humanml3d: the skip-transformer autoencoder 7 x 256, the denoiser 11 x 512), bfloat16
# autocast (named: train.cm.precision=auto is fp32 on CUDA, as bf16 stage 2
# diverged over thousands of steps; these runs are hundreds, for speed), and how busy it keeps the GPU: nvidia-smi's
# utilization sampled every 100 ms while each run trains, counted between its first and last
# log lines (the training itself, not the start-up). The eager step (batches from DataLoader
# workers) and the step replayed from a CUDA graph (train.*.cuda_graph=true: the motions on the
# GPU, train/captured_step.py) side by side in one run, then the CUDA-graph tests.
#
#   bash bench/gpu/train_check.sh [CARRY_DIR] [WORKERS]   (defaults .devcarry 8; logs to $OUT)
#
# A dry run of the script itself on a machine without a GPU: a stand-in nvidia-smi on PATH and
# DEVICE=cpu CONFIG=tiny STEPS_SCALE=0.01.
set -u
cd "$(dirname "$0")/../.."
source bench/gpu/setup.sh "${1:-.devcarry}"
workers=${2:-8}
device=${DEVICE:-cuda}
config=${CONFIG:-humanml3d}
scale=${STEPS_SCALE:-1}
data=/tmp/gpu_train_data
run=/tmp/gpu_train_run
busy() {  # name, seconds, command...: step() with the GPU's utilization sampled meanwhile
    local name=$1
    nvidia-smi --query-gpu=timestamp,utilization.gpu --format=csv,noheader,nounits -lms 100 \
        > "$OUT/$name.util" &
    local sampler=$!
    step "$@"
    kill "$sampler"
}
trainer() {  # name, stage, graph (true|false), batch, steps, extra...
    local name=$1 stage=$2 graph=$3 batch=$4
    local steps=$(python3 -c "print(max(20, int($5 * $scale)))"); shift 5
    busy "$name" 170 python3 -m mlct.cli train "$stage" --data "$data" --out "$run/$name" \
        --config "$config" --device "$device" --quiet "data.num_workers=$workers" \
        "train.$stage.cuda_graph=$graph" "train.$stage.batch_size=$batch" \
        "train.$stage.max_steps=$steps" "train.$stage.log_every=$((steps / 10))" \
        "train.$stage.val_every=100000" "train.$stage.ckpt_every=$steps" \
        "train.$stage.precision=bf16" "$@"
}
step synth 150 python3 -m mlct.cli data synth --out "$data" --num 600 --seed 0 --workers 16 --quiet
trainer ae_graph_64 ae true 64 1500
trainer cm_eager_64 cm false 64 400 --ae "$run/ae_graph_64"
trainer cm_graph_64 cm true 64 3000 --ae "$run/ae_graph_64"
trainer cm_graph_256 cm true 256 1000 --ae "$run/ae_graph_64"
trainer ae_eager_64 ae false 64 400
python3 - "$OUT" "$run" <<'PY' | tee "$OUT/summary.txt"
import datetime, json, statistics, sys
from pathlib import Path
out, run = Path(sys.argv[1]), Path(sys.argv[2])
print("run | steps | samples/s (median of the logged intervals) | ms per step | GPU utilization "
      "while training: samples, median, mean")
for util_file in sorted(out.glob("*.util")):
    name = util_file.stem
    stage = name.split("_")[0]
    log = run / name / stage / "log.jsonl"
    rows = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    rows = [r for r in rows if "samples_per_s" in r]
    if len(rows) < 2:
        print(f"{name}: no training log"); continue
    batch = int(name.rsplit("_", 1)[1])
    rates = [(b["step"] - a["step"]) * batch / (b["time"] - a["time"])
             for a, b in zip(rows, rows[1:])]
    start, end = rows[0]["time"], rows[-1]["time"]
    util = []
    for line in util_file.read_text().splitlines():
        try:
            stamp, value = [part.strip() for part in line.split(",")]
            when = datetime.datetime.strptime(stamp, "%Y/%m/%d %H:%M:%S.%f").timestamp()
        except ValueError:
            continue
        if start <= when <= end:
            util.append(int(value))
    rate = statistics.median(rates)
    print(f"{name} | {rows[-1]['step']} | {rate:.0f} | {1000 * batch / rate:.1f} | "
          f"{len(util)}, {statistics.median(util) if util else float('nan'):.0f}%, "
          f"{statistics.mean(util) if util else float('nan'):.0f}%")
PY
step pytest 200 python3 -m pytest -q -p no:cacheprovider tests/test_captured_step.py
