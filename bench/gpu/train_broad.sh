#!/usr/bin/env bash
# On a lent GPU, in one device call: tools/make_broad_model_gpu.sh on the datasets that
# CARRY_DIR/real/*.tar.xz hold (bench/gpu/dataset_carry.py pack), ending by END_S seconds after
# the start (default 540, for a call of 600), and what comes back in $OUT: model.tar (the
# exported model), logs.tar (each training's log.jsonl, the calibration's too) and the
# recipe's output. With SIDE_AE="overrides" (e.g. "ae.stages=2"), an autoencoder of those
# overrides trains from scratch beside it on the same data at a constant lr 1e-3 until the end,
# and its last checkpoint comes back as side_ae.tar.
#
#   bash bench/gpu/carry.sh .devcarry DATASET...; python bench/gpu/dataset_carry.py pack ...
#   bash bench/gpu/slim.sh on; (device call: bash bench/gpu/train_broad.sh .devcarry); bash bench/gpu/slim.sh off
set -u
cd "$(dirname "$0")/../.."
end_at=$(( $(date +%s) + ${END_S:-540} ))
carry=${1:-.devcarry}
source bench/gpu/setup.sh "$carry"
work=${WORK:-/tmp/broad}
mkdir -p "$work/real"
for archive in "$carry"/real/*.tar.xz; do
    python3 bench/gpu/dataset_carry.py unpack "$archive" "$work/real" || exit 1
done
side() {  # the side autoencoder, once the merged set exists
    while [ ! -f "$work/w/mixed/provenance.jsonl" ]; do
        [ "$(date +%s)" -lt "$end_at" ] || return 1; sleep 2
    done
    [ -f "$carry/minilm_tokens.txt" ] && python3 bench/gpu/minilm_tokens.py check \
        "$carry/minilm_tokens.txt" "$work/w/mixed"
    [ -n "${SIDE_AE:-}" ] || return 0
    # shellcheck disable=SC2086  # SIDE_AE is a list of overrides
    timeout $(( end_at - $(date +%s) - 20 )) mlct train ae --data "$work/w/mixed" \
        --out "$work/side" --device "${DEVICE:-cuda}" --quiet $SIDE_AE train.ae.lr=1e-3 \
        train.ae.lr_min=1e-3 train.ae.max_steps=1000000 train.ae.ckpt_every=1000 \
        train.ae.log_every=200 train.ae.val_every=5000 train.ae.precision=bf16 \
        > "$OUT/side_ae.txt" 2>&1
}
side > "$OUT/side.txt" 2>&1 &
side_pid=$!
END_AT=$end_at bash tools/make_broad_model_gpu.sh "$work/w" "$work/real"/* 2>&1 \
    | tee "$OUT/recipe.txt"
wait "$side_pid"
cat "$OUT/side.txt"
tar -cf "$OUT/model.tar" -C "$work/w" model
(cd "$work/w" && tar -cf "$OUT/logs.tar" $(ls -d run/*/log.jsonl calibration/*/log.jsonl 2>/dev/null))
if [ -d "$work/side/ae/checkpoints" ]; then
    last=$(ls -d "$work/side/ae/checkpoints"/step-* | sort -V | tail -1)
    tar -cf "$OUT/side_ae.tar" -C "$work/side" config.yaml ae/log.jsonl \
        "ae/checkpoints/$(basename "$last")" 2>/dev/null \
        || tar -cf "$OUT/side_ae.tar" -C "$work/side" .
fi
ls -la "$OUT"
