#!/usr/bin/env bash
# Issue 14's first bottleneck, probed on a lent GPU: is the autoencoder's reconstruction limited
# by its training budget or by its latent? The `small` preset's conv autoencoder (the bundle's
# shape, 3 tokens x 64) and the same with 6 tokens, each trained from scratch on the benchmark
# (mlct data synth --num 4000 --seed 0, as the bundle's) for 25,000 steps of 128 motions: ten
# times the samples of the recipe's 10,000 x 32, in minutes, with train.ae.cuda_graph=true. The
# two run side by side on the one GPU. Their weights come back to $OUT/<name>/ae/checkpoints
# (in $OUT/ae_capacity.tar) for the reconstruction bench on the CPU:
#   python bench/motion_quality.py --data synth4k --ae OUT/<name> --skip-generation
#
#   bash bench/gpu_ae_capacity.sh [CARRY_DIR] [STEPS]   (defaults .devcarry 25000)
# (a dry run without a GPU: a stand-in nvidia-smi on PATH, DEVICE=cpu NUM=200 and few STEPS)
set -u
cd "$(dirname "$0")/.."
final=${OUT:-/tmp/gpu_ae_capacity}  # gets one file, ae_capacity.tar: the logs and the weights
export OUT=/tmp/ae_probe_out
source bench/gpu_setup.sh "${1:-.devcarry}"
steps=${2:-25000}
data=/tmp/ae_probe_data
run=/tmp/ae_probe_run
step synth 150 python3 -m mlct.cli data synth --out "$data" --num "${NUM:-4000}" --seed 0 --workers 16 --quiet
probe() {  # name, overrides...: one autoencoder, in the background
    local name=$1; shift
    timeout 330 python3 -m mlct.cli train ae --data "$data" --out "$run/$name" --config small \
        --device "${DEVICE:-cuda}" --quiet data.num_workers=6 train.ae.cuda_graph=true \
        train.ae.batch_size=128 "train.ae.max_steps=$steps" train.ae.log_every=500 \
        train.ae.val_every=5000 train.ae.ckpt_every=2500 "$@" > "$OUT/$name.txt" 2>&1
    echo "== $name: exit $?" >> "$OUT/steps.txt"
}
probe tokens3 &
probe tokens6 ae.n_tokens=6 &
wait
cat "$OUT/steps.txt"
for name in tokens3 tokens6; do
    tail -n 3 "$OUT/$name.txt"
    dir="$run/$name/ae"
    latest=$(cat "$dir/checkpoints/latest" 2>/dev/null) || continue
    mkdir -p "$OUT/$name/ae/checkpoints/$latest"
    cp "$dir/checkpoints/$latest/model.safetensors" "$OUT/$name/ae/checkpoints/$latest/"
    echo "$latest" > "$OUT/$name/ae/checkpoints/latest"
    cp "$dir/log.jsonl" "$OUT/$name/ae/"
    python3 - "$dir/log.jsonl" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
train = [r for r in rows if "samples_per_s" in r]
val = [r for r in rows if "val_loss" in r]
if len(train) > 1:
    a, b = train[0], train[-1]
    print(f"step {b['step']}: {(b['step'] - a['step']) / (b['time'] - a['time']):.0f} steps/s, "
          f"val {[(r['step'], round(r['val_loss'], 4)) for r in val]}")
PY
done
mkdir -p "$final"
tar -cf "$final/ae_capacity.tar" -C "$OUT" .
ls -la "$final"
