#!/usr/bin/env bash
# On a lent GPU, in one device call: tools/make_broad_model_gpu.sh on the datasets that
# CARRY_DIR/real/*.tar.xz hold (bench/gpu/dataset_carry.py pack), ending by END_S seconds after
# the start (default 540, for a call of 600), and what comes back in $OUT: model.tar (the
# exported model), logs.tar (each training's log.jsonl, the calibration's too) and the
# recipe's output, with the check that the carried MiniLM rows cover the captions made there.
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
END_AT=$end_at bash tools/make_broad_model_gpu.sh "$work/w" "$work/real"/* 2>&1 \
    | tee "$OUT/recipe.txt"
[ -f "$carry/minilm_tokens.txt" ] && python3 bench/gpu/minilm_tokens.py check \
    "$carry/minilm_tokens.txt" "$work/w/mixed" | tee -a "$OUT/recipe.txt"
tar -cf "$OUT/model.tar" -C "$work/w" model
(cd "$work/w" && tar -cf "$OUT/logs.tar" $(ls -d run/*/log.jsonl calibration/*/log.jsonl 2>/dev/null))
ls -la "$OUT"
